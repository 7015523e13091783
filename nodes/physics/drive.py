"""Differential-drive command shaping: speed and acceleration limits, then wheel speeds."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class DiffDrive:
    """Turns a (v, w) body twist into left/right wheel speeds under speed and accel limits.

    ``update`` is called once per physics substep of ``dt`` seconds with the commanded
    twist; the applied twist moves towards it at most ``max_accel * dt`` per substep.
    """

    wheel_radius: float
    wheel_separation: float
    max_linear_speed: float
    max_angular_speed: float
    max_linear_accel: float
    max_angular_accel: float
    v: float = 0.0
    w: float = 0.0

    def update(self, v_cmd: float, w_cmd: float, dt: float) -> tuple[float, float]:
        """Apply limits for one substep; return (left, right) wheel speeds in rad/s."""
        v_cmd = min(max(v_cmd, -self.max_linear_speed), self.max_linear_speed)
        w_cmd = min(max(w_cmd, -self.max_angular_speed), self.max_angular_speed)
        self.v += _clamp(v_cmd - self.v, self.max_linear_accel * dt)
        self.w += _clamp(w_cmd - self.w, self.max_angular_accel * dt)
        half = 0.5 * self.wheel_separation * self.w
        return (self.v - half) / self.wheel_radius, (self.v + half) / self.wheel_radius


def _clamp(x: float, limit: float) -> float:
    return min(max(x, -limit), limit)
