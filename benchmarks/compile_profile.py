"""Where a cold start's compile time goes: numba's passes, LLVM, per kernel.

Runs the cold-start sequence of ``benchmarks/cold_start.py`` (a generated road, a
sensor frame, the robust ALDM, the naive detector, ``gym.make`` + ``reset`` + the first
``step``) in a child interpreter with an empty ``NUMBA_CACHE_DIR``, and splits the
compile time by what numba was doing:

* numba's front end: bytecode to typed IR (type inference, rewrites, inlining, SSA);
* lowering: typed IR to LLVM IR, in Python (numba's ``native_lowering`` pass minus the
  LLVM work it starts);
* LLVM optimisation: the pass managers numba runs on each kernel's module, *including*
  the copies of its callees linked into it (a caller's module is optimised again with
  everything it calls);
* machine code: LLVM's code generation of each module (``finalize_object``).

Times are exclusive (a callee compiled while its caller is typed counts for the
callee), wall clock, in one process: numba compiles in one thread. It also lists the
kernels with the most exclusive compile time. The split is read by wrapping numba's
compiler events and two llvmlite calls; if a numba release renames them the
corresponding rows read 0.

Run: ``.venv/bin/python -m benchmarks.compile_profile [--top 15]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

_CHILD = r"""
import collections, json, sys, time
from numba.core import codegen, event
from llvmlite.binding import newpassmanagers

passes = collections.defaultdict(float)  # exclusive time per numba pass
kernels = collections.defaultdict(float)  # exclusive time per compiled function
llvm = {"optimise": 0.0, "machine code": 0.0}
stack = []  # [start, time of children]


class Listener(event.Listener):
    def on_start(self, ev):
        stack.append([time.perf_counter(), 0.0])

    def on_end(self, ev):
        start, children = stack.pop()
        took = time.perf_counter() - start
        if stack:
            stack[-1][1] += took
        if ev.kind == "numba:run_pass":
            name, _, func = ev.data["name"].partition(" [")
            passes[name] += took - children
            kernels[func.rstrip("]")] += took - children


listener = Listener()
for kind in ("numba:compile", "numba:run_pass"):
    event.register(kind, listener)


def timed(cls, name, key):
    original = getattr(cls, name, None)
    if original is None:
        return

    def wrapper(self, *args, **kwargs):
        start = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            llvm[key] += time.perf_counter() - start

    setattr(cls, name, wrapper)


for cls in (newpassmanagers.ModulePassManager, newpassmanagers.FunctionPassManager):
    timed(cls, "run", "optimise")
timed(codegen.JitEngine, "finalize_object", "machine code")

start = time.perf_counter()
import gymnasium as gym
import aldm_gym
from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect

road = HighwayRoad({"seed": 0, "length": 1000.0})
pose = (*road.reference.position(500.0, road.lane_offset(1)), road.reference.heading_at(500.0))
frame = LineSensor().measure(road, tuple(float(v) for v in pose))
detect_lanes(frame)
naive_detect(frame)
env = gym.make("ALDMHighway-v0")
env.reset(seed=0)
env.step(1)
total = time.perf_counter() - start
print(json.dumps({"total": total, "passes": passes, "kernels": kernels, "llvm": llvm}))
"""

FRONT_END = (
    "translate_bytecode",
    "fixup_args",
    "ir_processing",
    "with_lifting",
    "inline_closure_likes",
    "rewrite_semantic_constants",
    "dead_branch_prune",
    "generic_rewrites",
    "make_function_op_code_to_jit_function",
    "inline_inlinables",
    "find_literally",
    "literal_unroll",
    "reconstruct_ssa",
    "literal_propagation_subpipeline",
    "nopython_type_inference",
    "strip_phis",
    "inline_overloads",
    "nopython_rewrites",
    "nopython_supported_feature_validation",
    "ir_legalization",
    "dead_code_elimination",
    "annotate_types",
    "parfor_pass",
    "pre_parfor_pass",
    "nopython_backend",
    "dump_parfor_diagnostics",
    "preserve_ir",
    "find_branches",
)
"""numba's passes before lowering (bytecode to typed IR); any other pass but
``native_lowering`` is reported and counted with them."""


def main(argv: list[str] | None = None) -> None:
    """Run the child and print the split and the slowest kernels."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=15, help="kernels to list")
    args = parser.parse_args(argv)
    print(
        f"machine: {os.uname().machine}, nproc={os.cpu_count()}, "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        env.pop("NUMBA_DISABLE_JIT", None)
        out = subprocess.run(
            [sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True
        )
    if out.returncode != 0:
        sys.exit(out.stderr[-2000:])
    data = json.loads(out.stdout.strip().splitlines()[-1])
    passes = data["passes"]
    llvm = data["llvm"]
    lowering = passes.get("native_lowering", 0.0)
    front = sum(v for k, v in passes.items() if k != "native_lowering")
    compiled = front + lowering
    rows = [
        ("numba front end (bytecode -> typed IR)", front),
        ("lowering to LLVM IR (Python)", lowering - llvm["optimise"] - llvm["machine code"]),
        ("LLVM optimisation (callees' copies included)", llvm["optimise"]),
        ("LLVM machine code", llvm["machine code"]),
    ]
    print(f"to the first env step: {data['total']:.1f} s, of which compiling {compiled:.1f} s")
    print("| compile stage | time [s] | share |")
    print("|---|---:|---:|")
    for name, took in rows:
        print(f"| {name} | {took:.1f} | {100.0 * took / compiled:.0f} % |")
    unknown = sorted(k for k in passes if k not in FRONT_END and k != "native_lowering")
    if unknown:
        print(f"(front end also holds passes {unknown})")
    print(f"\nslowest kernels (exclusive compile time, {len(data['kernels'])} functions):")
    top = sorted(data["kernels"].items(), key=lambda kv: -kv[1])[: args.top]
    for name, took in top:
        print(f"  {took:5.1f} s  {name}")


if __name__ == "__main__":
    main()
