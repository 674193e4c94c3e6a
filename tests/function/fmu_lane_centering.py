"""A function under test as an FMU's Python source: pythonfmu packages it (FMI 2.0
co-simulation) in the tests. Pure pursuit on the perceived ego lane's centre (its
curvature through a first-order lag, state that a reset must clear) and a time-gap
ACC on the nearest object slot in it, from the inputs of aldm-gym's FMU convention
(docs/api.md) only."""

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Real

ROLES = ("ego_left", "ego_right")
SLOTS = 4


class LaneCentering(Fmi2Slave):
    """Reads ``ego.speed``, the ego lines' cubics and four object slots; writes
    ``curvature`` and ``acceleration``."""

    author = "aldm-gym tests"
    description = "pure pursuit + time gap, on aldm-gym's FMU convention"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.values = {}
        self.curvature = 0.0
        self.acceleration = 0.0
        names = ["ego.speed"]
        names += [f"line.{r}.{f}" for r in ROLES for f in ("valid", "c0", "c1", "c2", "c3")]
        names += [
            f"object[{i}].{f}" for i in range(SLOTS) for f in ("x", "y", "vx", "length", "valid")
        ]
        for name in names:
            self.values[name] = 0.0
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    getter=lambda n=name: self.values[n],
                    setter=lambda v, n=name: self.values.__setitem__(n, v),
                )
            )
        # exact initial values: no initial unknowns to declare (FMI 2.0 §2.2.8)
        for name in ("curvature", "acceleration"):
            self.register_variable(
                Real(name, causality=Fmi2Causality.output, initial=Fmi2Initial.exact)
            )

    def _centre(self, x):
        ys = []
        for role in ROLES:
            if self.values[f"line.{role}.valid"] > 0.5:
                c = [self.values[f"line.{role}.c{k}"] for k in range(4)]
                ys.append(c[0] + c[1] * x + c[2] * x * x + c[3] * x**3)
        if len(ys) == 2:
            return 0.5 * (ys[0] + ys[1])
        if self.values["line.ego_left.valid"] > 0.5:
            return ys[0] - 1.75
        if self.values["line.ego_right.valid"] > 0.5:
            return ys[0] + 1.75
        return None

    def do_step(self, current_time, step_size):
        v = self.values["ego.speed"]
        x = max(12.0, v)
        y = self._centre(x)
        if y is not None:
            # a first-order lag on the curvature: state that only fmi2Reset clears
            self.curvature += 0.5 * (2.0 * y / (x * x + y * y) - self.curvature)
        accel = 0.5 * (16.7 - v)
        for i in range(SLOTS):
            if self.values[f"object[{i}].valid"] < 0.5:
                continue
            ox, oy = self.values[f"object[{i}].x"], self.values[f"object[{i}].y"]
            centre = self._centre(ox) if ox > 0 else None
            if ox <= 0 or centre is None or abs(oy - centre) > 2.5:
                continue
            gap = ox - 0.5 * self.values[f"object[{i}].length"] - 2.0
            accel = min(accel, 0.25 * (gap - 4.0 - 1.8 * v) + 0.6 * self.values[f"object[{i}].vx"])
        self.acceleration = max(-9.0, min(2.0, accel))
        return True
