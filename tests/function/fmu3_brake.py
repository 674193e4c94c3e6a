"""A function under test as an FMI 3.0 FMU's Python source (pythonfmu3 packages it in
the tests): brakes towards 15 m/s and asks for the left lane at 1 s, with a Float64
and an Int32 output; it counts its steps itself, so only a reset starts the count again."""

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Initial, Fmi3Slave, Int32


class Brake3(Fmi3Slave):
    """Longitudinal: ``acceleration``; and a ``lane_change`` request."""

    author = "aldm-gym tests"
    description = "FMI 3.0: brakes to 15 m/s, asks for the left lane once"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.speed = 0.0
        self.acceleration = 0.0
        self.lane_change = 0
        self.time = 0.0
        self.steps = 0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent))
        self.register_variable(
            Float64(
                "ego.speed",
                causality=Fmi3Causality.input,
                getter=lambda: self.speed,
                setter=lambda v: setattr(self, "speed", v),
            )
        )
        self.register_variable(
            Float64("acceleration", causality=Fmi3Causality.output, initial=Fmi3Initial.exact)
        )
        self.register_variable(
            Int32("lane_change", causality=Fmi3Causality.output, initial=Fmi3Initial.exact)
        )

    def do_step(self, current_time, step_size):
        self.acceleration = max(-3.0, min(1.0, 0.5 * (15.0 - self.speed)))
        self.steps += 1  # the FMU's own count: only fmi3Reset starts it again
        self.lane_change = 1 if self.steps == 11 else 0
        return True
