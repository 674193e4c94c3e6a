"""``python -m aldm_gym``: the ``aldm-gym`` command line."""

from __future__ import annotations

import sys

from aldm_gym.cli import main

sys.exit(main())
