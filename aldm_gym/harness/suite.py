"""A suite of scenario runs: plan them, play them in parallel, summarise them.

A suite is a parameter-variation file (its concrete runs, minus those that break a
``ConstraintGroup`` of the scenario's declarations, as the OSC-ALKS files ask), a
folder of them, or a folder of concrete scenarios (each played with its default
parameters); every run is played for every detector and marking model. ``max_runs``
keeps a subset of a file's runs that covers as many parameter values as it can
(:func:`_subset`); the summary's ``runs`` column says how many were played and
judged, ``not_judged`` how many the function under test never drove in, ``errors`` how
many could not be played (a scenario error, or a collision before the function was
activated), and the pass rate is over the judged ones.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.errors import AldmGymError, ScenarioError
from aldm_gym.function import Function, close_function, load_function
from aldm_gym.harness.criteria import RunResult, run_scenario
from aldm_gym.xmlfile import parse_xml

__all__ = ["Job", "format_table", "plan_suite", "play_suite", "summarise", "write_outputs"]


@dataclass(frozen=True)
class Job:
    """One run to play: a scenario file, its parameters, a detector and a marking
    model, the other env settings (``config``, as JSON) and the function under test
    (a ``--function`` SPEC)."""

    xosc: str
    parameters: tuple[tuple[str, str], ...]
    detector: str
    marking_model: str
    config: str = "{}"
    function: str = "builtin"


def _is_variation(path: Path) -> bool:
    root = parse_xml(path).getroot()
    return root.find("ParameterValueDistribution") is not None


def _spread(n: int) -> list[int]:
    """``0..n-1`` in an evenly spreading order (van der Corput: 0, n/2, n/4, 3n/4, ...),
    each index once."""
    order: list[int] = []
    seen: set[int] = set()
    k = 0
    while len(order) < n:
        x, f, j = 0.0, 0.5, k
        while j:
            x += f * (j & 1)
            j >>= 1
            f *= 0.5
        i = int(x * n)
        if i not in seen:
            seen.add(i)
            order.append(i)
        k += 1
        if k > 4 * n + 64:  # float rounding left some out: append them in order
            order += [i for i in range(n) if i not in seen]
            break
    return order


def _subset(runs: list[Any], most: int | None) -> list[Any]:
    """At most ``most`` runs covering as many parameter values as they can: greedily,
    each next run is the one with the most (parameter, value) pairs not yet covered,
    ties going to the run that spreads the picks most evenly through the variation's
    order (:func:`_spread`); returned in the variation's order."""
    if most is None or len(runs) <= most:
        return runs
    pairs = [set(r.parameters.items()) for r in runs]
    rank = {i: k for k, i in enumerate(_spread(len(runs)))}
    covered: set[Any] = set()
    chosen: set[int] = set()
    for _ in range(most):
        best = max(
            (i for i in range(len(runs)) if i not in chosen),
            key=lambda i: (len(pairs[i] - covered), -rank[i]),
        )
        chosen.add(best)
        covered |= pairs[best]
    return [runs[i] for i in sorted(chosen)]


def plan_suite(
    path: str | Path,
    detectors: Sequence[str],
    marking_models: Sequence[str],
    max_runs: int | None = None,
    config: dict[str, Any] | None = None,
    function: str = "builtin",
) -> list[Job]:
    """The jobs of a suite (see the module docstring); ``config``: more env settings
    for every run (merged last, as :func:`~aldm_gym.harness.criteria.run_scenario`
    merges them); ``function``: the function under test's SPEC
    (:func:`~aldm_gym.function.load_function`).

    :raises ScenarioError: a file that cannot be read; :class:`FileNotFoundError`:
        ``path`` does not exist.
    """
    from aldm_gym.scenario.declarations import declarations_from_xml
    from aldm_gym.scenario.distributions import expand_variation, filter_runs

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist")
    concrete: list[tuple[Path, dict[str, str]]] = []
    files = sorted(path.glob("*.xosc")) if path.is_dir() else [path]
    if path.is_dir():
        variations = [f for f in files if _is_variation(f)]
        files = variations or files  # a folder: its variation files if it has any
    for file in files:
        if not _is_variation(file):
            concrete.append((file, {}))
            continue
        scenario, runs = expand_variation(file)
        root = parse_xml(scenario).getroot()
        decls = declarations_from_xml(root.find("ParameterDeclarations"))
        kept, _ = filter_runs(runs, decls, scenario.name)
        concrete.extend((scenario, dict(r.parameters)) for r in _subset(kept, max_runs))
    if not concrete:
        raise ScenarioError(f"{path}: no concrete scenario (.xosc) found")
    settings = json.dumps(config or {}, sort_keys=True)
    return [
        Job(str(file), tuple(sorted(params.items())), det, mm, settings, function)
        for file, params in concrete
        for det in detectors
        for mm in marking_models
    ]


_FUNCTIONS: dict[str, Function] = {}
"""The functions under test this process has loaded, by SPEC: a trained model is
loaded once per worker and reset before each run."""


def _function(spec: str) -> Function | str:
    """The loaded function of ``spec``, kept for the worker's next runs; or ``spec``
    itself for a function with resources to free (an FMU), which
    :func:`~aldm_gym.harness.criteria.run_scenario` loads and closes per run (a worker
    ends without a chance to close what it keeps)."""
    if spec not in _FUNCTIONS:
        function = load_function(spec)
        if close_function(function):
            return spec
        _FUNCTIONS[spec] = function
    return _FUNCTIONS[spec]


def _play(job: Job) -> RunResult:
    try:
        result = run_scenario(
            job.xosc,
            dict(job.parameters),
            job.detector,
            job.marking_model,
            config=json.loads(job.config),
            function=_function(job.function),
        )
        result.function = job.function
        return result
    except AldmGymError as exc:  # a bad file, parameter set or map: a row, not a crash
        return RunResult(
            scenario=Path(job.xosc).name,
            detector=job.detector,
            marking_model=job.marking_model,
            parameters=dict(job.parameters),
            function=job.function,
            error=str(exc),
        )


def play_suite(
    jobs: Sequence[Job], processes: int = 2, progress: bool = True, address: str | None = None
) -> list[RunResult]:
    """Play the jobs in ``processes`` worker processes, or on the Ray cluster at
    ``address`` (one task per run, as many at once as it has CPUs); results in the
    order of the jobs."""
    import warnings

    from tqdm import tqdm

    bar = tqdm(total=len(jobs), desc="scenario runs", unit="run", disable=not progress or None)
    results: list[RunResult] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if address is not None:
            from ray.util.multiprocessing import Pool as RayPool

            with RayPool(ray_address=address) as pool:
                for r in pool.imap(_play, jobs, chunksize=1):
                    results.append(r)
                    bar.update()
        elif processes <= 1:
            for job in jobs:
                results.append(_play(job))
                bar.update()
        else:
            import multiprocessing as mp

            with mp.get_context("spawn").Pool(processes) as pool:
                for r in pool.imap(_play, jobs, chunksize=1):
                    results.append(r)
                    bar.update()
    bar.close()
    return results


def summarise(results: Sequence[RunResult]) -> list[dict[str, Any]]:
    """Per scenario × detector × marking model: runs, pass rate, collisions,
    departures, min TTC, min time gap, and the first failing parameter sets."""
    groups: dict[tuple[str, str, str], list[RunResult]] = {}
    for r in results:
        groups.setdefault((r.scenario, r.detector, r.marking_model), []).append(r)
    rows = []
    for (scenario, det, mm), rs in groups.items():
        failing = [r for r in rs if not r.passed and not r.error]
        played = [r for r in rs if not r.error]
        not_judged = sum(not r.judged for r in rs)
        rows.append(
            {
                "scenario": scenario,
                "detector": det,
                "marking_model": mm,
                "runs": len(played),
                "pass_rate": sum(r.passed for r in played) / len(played) if played else math.nan,
                "collisions": sum(r.collision for r in rs),
                "departure_runs": sum(r.departures > 0 for r in rs),
                "gap_failures": sum(not r.time_gap for r in rs),
                "not_judged": not_judged,
                "errors": len(rs) - len(played) - not_judged,
                "min_ttc_s": min(r.min_ttc_s for r in rs),
                "min_time_gap_s": min(r.min_time_gap_s for r in rs),
                "failing": " | ".join(
                    ";".join(f"{k}={v}" for k, v in r.parameters.items()) or "(defaults)"
                    for r in failing[:3]
                ),
            }
        )
    return rows


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """The summary as a console table."""
    head = (
        f"{'scenario':<44} {'detector':<12} {'model':<8} {'runs':>5} {'pass':>6} "
        f"{'coll':>5} {'dep':>5} {'gap':>5} {'minTTC':>7} {'minGap':>7} {'n/j':>4} {'err':>4}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        name = r["scenario"].replace("alks_scenario_", "").replace("_template.xosc", "")
        lines.append(
            f"{name[:44]:<44} {r['detector']:<12} {r['marking_model']:<8} {r['runs']:>5} "
            f"{100 * r['pass_rate']:>5.0f}% {r['collisions']:>5} {r['departure_runs']:>5} "
            f"{r['gap_failures']:>5} {_num(r['min_ttc_s']):>7} {_num(r['min_time_gap_s']):>7} "
            f"{r['not_judged']:>4} {r['errors']:>4}"
        )
    lines.append(
        "pass: share of runs meeting every criterion; coll: runs with a collision; dep: "
        "runs with a lane departure; gap: runs whose time gap stayed short > 3 s; min "
        "TTC / min gap [s] over all runs; n/j: runs the function never drove in (not "
        "judged); err: runs that could not be played (not in the pass rate)"
    )
    return "\n".join(lines)


def _num(x: float) -> str:
    return "inf" if not math.isfinite(x) else f"{x:.2f}"


def write_outputs(results: Sequence[RunResult], rows: Sequence[dict[str, Any]], out: Path) -> None:
    """``scenario_runs.csv`` (one row per run), ``scenario_summary.csv`` and
    ``scenario_pass_rates.png`` in ``out``."""
    runs = [r.row() for r in results]
    for name, table in (("scenario_runs.csv", runs), ("scenario_summary.csv", list(rows))):
        with open(out / name, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)
    _plot(rows, out / "scenario_pass_rates.png")


def _plot(rows: Sequence[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    keys = list(dict.fromkeys((r["detector"], r["marking_model"]) for r in rows))
    fig, ax = plt.subplots(figsize=(max(8.0, 0.6 * len(scenarios) + 3), 4.5))
    width = 0.8 / max(len(keys), 1)
    for i, key in enumerate(keys):
        vals = [
            next(
                (
                    100 * r["pass_rate"]
                    for r in rows
                    if r["scenario"] == s and (r["detector"], r["marking_model"]) == key
                ),
                np.nan,
            )
            for s in scenarios
        ]
        ax.bar(np.arange(len(scenarios)) + i * width, vals, width, label=f"{key[0]} / {key[1]}")
    labels = [s.replace("alks_scenario_", "").replace("_template.xosc", "")[:22] for s in scenarios]
    ax.set_xticks(
        np.arange(len(scenarios)) + 0.4 - width / 2, labels, rotation=60, ha="right", fontsize=8
    )
    ax.set_ylabel("runs passing every R157 criterion [%]")
    ax.set_ylim(0, 105)
    # above the axes: inside, it would hide the low bars it is meant to explain
    ax.legend(
        fontsize=8, ncol=min(len(keys), 6), loc="lower center", bbox_to_anchor=(0.5, 1.0),
        frameon=False,
    )  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
