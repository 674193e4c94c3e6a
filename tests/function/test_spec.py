"""``--function SPEC``: every kind loads, every mistake is named."""

from __future__ import annotations

from pathlib import Path

import pytest

from aldm_gym.errors import InputError
from aldm_gym.function import BuiltinFunction, CallableFunction, FunctionOutput, load_function

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "lane_centering.py"


def test_builtin_and_its_lane_change_modes() -> None:
    assert isinstance(load_function("builtin"), BuiltinFunction)
    rule = load_function("builtin:rule_based")
    assert isinstance(rule, BuiltinFunction) and rule.lane_changes == "rule_based"
    with pytest.raises(InputError, match="builtin:none, builtin:rule_based"):
        load_function("builtin:mobil")


def test_a_class_in_a_file_is_instantiated() -> None:
    fn = load_function(f"{EXAMPLE}:PurePursuitLKA")
    assert type(fn).__name__ == "PurePursuitLKA"
    assert fn.domains == frozenset({"lateral"})


def test_a_module_attribute_and_a_plain_callable() -> None:
    fn = load_function("tests.function.test_spec:brake")
    assert isinstance(fn, CallableFunction)
    assert fn.domains == frozenset({"longitudinal"})


def brake(inputs: object) -> FunctionOutput:
    """A plain callable taking the longitudinal domain."""
    return FunctionOutput(acceleration=-1.0)


brake.domains = frozenset({"longitudinal"})  # type: ignore[attr-defined]

NOT_A_FUNCTION = object()


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("no.such.module:Thing", "cannot import no.such.module"),
        (f"{EXAMPLE}:Nope", r"has no 'Nope'; it has \[.*'PurePursuitLKA'"),
        ("missing_file.py:Thing", "no file missing_file.py"),
        ("does/not/exist", "no such file, and not module:attr"),
        ("tests.function.test_spec:NOT_A_FUNCTION", "not a function under test: it has no step"),
        ("missing.fmu", "no FMU at missing.fmu"),
    ],
)
def test_mistakes_are_named(spec: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        load_function(spec)


class NeedsArguments:
    """A class that cannot be made without arguments."""

    domains = frozenset()

    def __init__(self, gain: float) -> None:
        self.gain = gain


def test_a_user_module_that_fails_is_named_not_a_traceback(tmp_path: Path) -> None:
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('no licence')\n")
    with pytest.raises(InputError, match=r"importing .*broken\.py raised RuntimeError: no licence"):
        load_function(f"{broken}:Thing")
    with pytest.raises(InputError, match=r"NeedsArguments\(\) raised TypeError.*without arguments"):
        load_function("tests.function.test_spec:NeedsArguments")
