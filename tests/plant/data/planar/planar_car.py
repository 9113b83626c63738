"""A supplier's car as it might ship (built into an FMU by pythonfmu in the tests): a
kinematic bicycle model on a plane, with its own names and units and no declared units.

Outputs: ``x``/``y`` east/north position (m), ``yaw`` counter-clockwise from east (rad,
wrapped to [-pi, pi)), ``speed_kmh`` (km/h), ``yaw_rate_dps`` (deg/s). Inputs: ``pedal``
(0..1: target speed as a fraction of ``v_max_kmh``, reached with a lag ``tau``),
``steer_deg`` (road-wheel angle, deg, left positive). Parameters: ``yaw0`` (rad), ``v0_kmh``.
Each step moves along the exact arc of the step's mean speed and yaw rate.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PlanarCar(Fmi2Slave):
    author = "a supplier"
    description = "planar kinematic bicycle car"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.wheelbase = 2.7
        self.v_max_kmh = 72.0
        self.tau = 2.0
        self.yaw0 = 0.0
        self.v0_kmh = 0.0
        self.pedal = 0.0
        self.steer_deg = 0.0
        self.x = 0.0
        self.y = 0.0
        self.yaw = 0.0
        self.speed_kmh = 0.0
        self.yaw_rate_dps = 0.0
        for name in ("wheelbase", "v_max_kmh", "tau", "yaw0", "v0_kmh"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        for name in ("pedal", "steer_deg"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("x", "y", "yaw", "speed_kmh", "yaw_rate_dps"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        self.yaw = (self.yaw0 + math.pi) % (2.0 * math.pi) - math.pi
        self.speed_kmh = self.v0_kmh
        self.yaw_rate_dps = math.degrees(self._rate(self.speed_kmh / 3.6))

    def _rate(self, v):
        return v * math.tan(math.radians(self.steer_deg)) / self.wheelbase

    def do_step(self, current_time, step_size):
        v = self.speed_kmh / 3.6
        target = self.pedal * self.v_max_kmh / 3.6
        v_new = target + (v - target) * math.exp(-step_size / self.tau)
        v_mid = 0.5 * (v + v_new)
        r = self._rate(v_mid)
        yaw_new = self.yaw + r * step_size
        if abs(r * step_size) > 1e-9:
            self.x += v_mid / r * (math.sin(yaw_new) - math.sin(self.yaw))
            self.y -= v_mid / r * (math.cos(yaw_new) - math.cos(self.yaw))
        else:
            mid = self.yaw + 0.5 * r * step_size
            self.x += v_mid * step_size * math.cos(mid)
            self.y += v_mid * step_size * math.sin(mid)
        self.yaw = (yaw_new + math.pi) % (2.0 * math.pi) - math.pi
        self.speed_kmh = v_new * 3.6
        self.yaw_rate_dps = math.degrees(self._rate(v_new))
        return True
