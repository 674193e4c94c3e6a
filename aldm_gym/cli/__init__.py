"""The ``aldm-gym`` command line: one module per subcommand.

* ``aldm-gym compare`` (:mod:`aldm_gym.cli.compare`): naive vs ALDM vs ground truth on
  the same seeded frames of both road models, then in closed loop.
* ``aldm-gym plot`` (:mod:`aldm_gym.cli.plot`): one frame, naive and ALDM side by side.
* ``aldm-gym scenario`` (:mod:`aldm_gym.cli.scenario`): OpenSCENARIO files on the env.
* ``aldm-gym osi`` (:mod:`aldm_gym.cli.osi`): the line sensor and a detector on an
  ASAM OSI trace.
* ``aldm-gym train`` (:mod:`aldm_gym.cli.train`): train a PPO lane-change policy.
* ``aldm-gym tune`` (:mod:`aldm_gym.cli.tune`): a hyperparameter search over short
  trainings.
* ``aldm-gym evaluate`` (:mod:`aldm_gym.cli.evaluate`): a trained policy against the
  rule-based ones.

Each subcommand module has ``add_parser(subparsers)``, which declares its arguments
and sets ``func`` (its ``run(args) -> exit code``) as the parser default;
:func:`main` calls it. A bad argument ends, whether argparse finds it (the types of
:mod:`aldm_gym.cli.argtypes`) or the command does
(:class:`~aldm_gym.cli.argtypes.BadArgument`), in the subcommand's usage, one line
naming the argument and exit code 2. Building the parser imports neither
stable-baselines3, torch nor matplotlib.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from aldm_gym import __version__
from aldm_gym.cli import compare, evaluate, osi, plot, scenario, train, tune
from aldm_gym.cli.argtypes import BadArgument
from aldm_gym.errors import AldmGymError

SUBCOMMANDS = (compare, plot, scenario, osi, train, tune, evaluate)
"""The subcommand modules, in the order of ``aldm-gym --help``."""


class _DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows an argument's default, unless it has none to show (``None``, a flag's
    ``False``, an empty list): those helps name the effective default themselves,
    e.g. "(49152; --quick 1024)"."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        default = action.default
        if default is None or default is False or (isinstance(default, list) and not default):
            return action.help
        return super()._get_help_string(action)


class _SubcommandParser(argparse.ArgumentParser):
    """A subcommand's parser: ``--help`` shows every default."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", _DefaultsFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``aldm-gym``."""
    parser = argparse.ArgumentParser(
        prog="aldm-gym",
        description="Lane detection on an emulated CarMaker line sensor: naive vs ALDM.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(
        dest="command", required=True, parser_class=_SubcommandParser, metavar="COMMAND"
    )
    for command in SUBCOMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aldm-gym``: parse ``argv`` and run the subcommand; its exit code.

    An unknown argument is reported with the usage of the subcommand it was given to
    (argparse would print the top-level usage), and exits with code 2; so is a
    :class:`~aldm_gym.cli.argtypes.BadArgument` raised while the subcommand runs, and
    any error of the package's (:class:`~aldm_gym.errors.AldmGymError`: a setting, a
    file, a map, a trace) that escapes it.
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    sub = parser._subparsers._group_actions[0].choices[args.command]  # type: ignore[union-attr]
    while sub._subparsers is not None:  # a command with actions (``scenario run``)
        group = sub._subparsers._group_actions[0]
        sub = group.choices[getattr(args, group.dest)]
    if extra:
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    if getattr(args, "env_file", None):  # --config: its settings, then --env's over them
        args.env = [*args.env_file, *args.env]
    try:
        return int(args.func(args))
    except BadArgument as exc:
        sub.error(str(exc))
    except AldmGymError as exc:
        sub.error(str(exc))  # bad input a command did not name more precisely
    except KeyboardInterrupt:  # Ctrl-C (or SIGTERM during a training) outside a safe point
        return 130
