"""The declarative config validator (aldm_gym.config): rules, messages, normalisation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from aldm_gym.config import setting, validate


@dataclass(frozen=True)
class _Demo:
    n: int = setting(3, lo=1, hi=10, integer=True)
    lo: float = setting(1.0, lo=0.0)
    hi: float = setting(2.0, lo="lo", hi=100.0)
    flag: bool = setting(False)
    mode: str = setting("a", choices=("a", "b"))
    pair: tuple[float, float] = setting((1.0, 2.0), kind="pair", lo=0.0, hi=10.0)
    speeds: list[float] = setting([1.0, 2.0], lo=0.0, hi=5.0, increasing=True)
    maybe: float | None = setting(None, lo=0.0, hi=1.0, optional=True)

    def __post_init__(self) -> None:
        validate(self, "demo")


def test_defaults_pass_and_lists_are_not_shared() -> None:
    a, b = _Demo(), _Demo()
    assert a == b
    assert a.speeds is not b.speeds


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n": 0}, r"demo\.n must be >= 1"),
        ({"n": 11}, r"demo\.n must be <= 10"),
        ({"n": 2.5}, r"demo\.n must be an integer"),
        ({"n": "3"}, r"demo\.n must be a finite number"),
        ({"n": True}, r"demo\.n must be a finite number"),
        ({"lo": float("nan")}, r"demo\.lo must be a finite number"),
        ({"lo": float("inf")}, r"demo\.lo must be a finite number"),
        ({"lo": 5.0, "hi": 4.0}, r"demo\.hi must be >= 5\.0"),
        ({"flag": 1}, r"demo\.flag must be a bool"),
        ({"mode": "c"}, r"demo\.mode must be one of \['a', 'b'\]"),
        ({"pair": (3.0, 1.0)}, r"demo\.pair must be \(min, max\)"),
        ({"pair": (1.0,)}, r"demo\.pair must be a \(min, max\) pair"),
        ({"speeds": []}, r"demo\.speeds must be a non-empty list"),
        ({"speeds": [2.0, 1.0]}, r"demo\.speeds must be increasing"),
        ({"speeds": [1.0, 9.0]}, r"demo\.speeds\[1\] must be <= 5\.0"),
        ({"speeds": "12"}, r"demo\.speeds must be a sequence of numbers"),
        ({"maybe": 2.0}, r"demo\.maybe must be <= 1\.0"),
    ],
)
def test_rules_reject_bad_values_naming_the_key(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _Demo(**kwargs)


def test_numpy_scalars_become_plain_numbers() -> None:
    d = _Demo(n=np.int64(4), lo=np.float32(0.5), flag=np.bool_(True), pair=[np.int64(1), 3])
    assert type(d.n) is int and d.n == 4
    assert type(d.lo) is float and d.lo == 0.5
    assert d.flag is True
    assert d.pair == (1.0, 3.0) and all(type(v) is float for v in d.pair)
    assert _Demo(n=3.0).n == 3 and type(_Demo(n=3.0).n) is int
