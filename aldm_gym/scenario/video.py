"""An animated GIF of a scenario run (Pillow, which matplotlib already needs)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["write_gif"]


def write_gif(frames: Sequence[np.ndarray], path: str | Path, fps: float = 10.0) -> None:
    """Write ``(H, W, 3)`` uint8 frames as an animated GIF playing at ``fps``."""
    from PIL import Image

    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames if f is not None]
    if not images:
        raise ValueError("no frames to write")
    images[0].save(
        str(path),
        save_all=True,
        append_images=images[1:],
        duration=max(round(1000.0 / fps), 20),
        loop=0,
    )
