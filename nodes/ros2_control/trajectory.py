"""A joint trajectory sampled as ros2_controllers' joint_trajectory_controller samples it
(``trajectory.cpp`` of the Jazzy branch): before the first point, from the state the
trajectory started at; between points, a spline chosen by what both points carry (positions
only: linear; with velocities: cubic; with accelerations too: quintic); after the last
point, the last point held. With ``interpolation_method: none`` the next point is taken as
it is. Times are integer nanoseconds; only the spline arithmetic is in floating point, in the
order upstream writes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

NS_PER_S = 1_000_000_000


@dataclass
class Point:
    """A trajectory point: time from the trajectory's start (ns) and per-joint values
    (empty lists where the point does not give them)."""

    time_ns: int
    positions: list[float]
    velocities: list[float] = field(default_factory=list)
    accelerations: list[float] = field(default_factory=list)


@dataclass
class Sample:
    """What the trajectory asks for at a time: positions, velocities, accelerations; and
    whether the time is past the last point."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    past_end: bool


def _powers(n: int, x: float) -> list[float]:
    out = [1.0]
    for _ in range(n):
        out.append(out[-1] * x)
    return out


def interpolate(t_a: int, a: Point, t_b: int, b: Point, t_ns: int) -> Sample:
    """The spline between ``a`` at ``t_a`` and ``b`` at ``t_b`` sampled at ``t_ns``
    (upstream's ``interpolate_between_points``)."""
    so_far = (t_ns - t_a) / NS_PER_S
    between = (t_b - t_a) / NS_PER_S
    has_vel = bool(a.velocities) and bool(b.velocities)
    has_acc = bool(a.accelerations) and bool(b.accelerations)
    if so_far < 0.0:
        so_far, has_vel, has_acc = 0.0, False, False
    if so_far > between:
        so_far, has_vel, has_acc = between, False, False
    t = _powers(5, so_far)
    dim = len(a.positions)
    pos, vel, acc = [0.0] * dim, [0.0] * dim, [0.0] * dim
    if not has_vel and not has_acc:
        for i in range(dim):
            c0, c1 = a.positions[i], 0.0
            if between != 0.0:
                c1 = (b.positions[i] - a.positions[i]) / between
            pos[i] = t[0] * c0 + t[1] * c1
            vel[i] = t[0] * c1
    elif has_vel and not has_acc:
        T = _powers(3, between)
        for i in range(dim):
            p0, v0, p1, v1 = a.positions[i], a.velocities[i], b.positions[i], b.velocities[i]
            c2 = c3 = 0.0
            if between != 0.0:
                c2 = (-3.0 * p0 + 3.0 * p1 - 2.0 * v0 * T[1] - v1 * T[1]) / T[2]
                c3 = (2.0 * p0 - 2.0 * p1 + v0 * T[1] + v1 * T[1]) / T[3]
            pos[i] = t[0] * p0 + t[1] * v0 + t[2] * c2 + t[3] * c3
            vel[i] = t[0] * v0 + t[1] * 2.0 * c2 + t[2] * 3.0 * c3
            acc[i] = t[0] * 2.0 * c2 + t[1] * 6.0 * c3
    else:
        T = _powers(5, between)
        for i in range(dim):
            p0, v0, a0 = a.positions[i], a.velocities[i], a.accelerations[i]
            p1, v1, a1 = b.positions[i], b.velocities[i], b.accelerations[i]
            c2, c3, c4, c5 = 0.5 * a0, 0.0, 0.0, 0.0
            if between != 0.0:
                c3 = (-20.0 * p0 + 20.0 * p1 - 3.0 * a0 * T[2] + a1 * T[2] - 12.0 * v0 * T[1]
                      - 8.0 * v1 * T[1]) / (2.0 * T[3])
                c4 = (30.0 * p0 - 30.0 * p1 + 3.0 * a0 * T[2] - 2.0 * a1 * T[2]
                      + 16.0 * v0 * T[1] + 14.0 * v1 * T[1]) / (2.0 * T[4])
                c5 = (-12.0 * p0 + 12.0 * p1 - a0 * T[2] + a1 * T[2] - 6.0 * v0 * T[1]
                      - 6.0 * v1 * T[1]) / (2.0 * T[5])
            pos[i] = (t[0] * p0 + t[1] * v0 + t[2] * c2 + t[3] * c3 + t[4] * c4
                      + t[5] * c5)
            vel[i] = (t[0] * v0 + t[1] * 2.0 * c2 + t[2] * 3.0 * c3 + t[3] * 4.0 * c4
                      + t[4] * 5.0 * c5)
            acc[i] = t[0] * 2.0 * c2 + t[1] * 6.0 * c3 + t[2] * 12.0 * c4 + t[3] * 20.0 * c5
    return Sample(pos, vel, acc, past_end=False)


class Trajectory:
    """A trajectory started at ``start_ns`` from ``before`` (the state when it arrived)."""

    def __init__(self, points: list[Point], start_ns: int, before: Point, before_ns: int):
        self.points = points
        self.start_ns = start_ns
        self.before = before
        self.before_ns = before_ns

    @property
    def end_ns(self) -> int:
        """The time of the last point."""
        return self.start_ns + self.points[-1].time_ns

    def sample(self, t_ns: int, interpolate_splines: bool = True) -> Sample:
        """The desired state at ``t_ns`` (upstream's ``Trajectory::sample``)."""
        first = self.points[0]
        t_first = self.start_ns + first.time_ns
        if t_ns < t_first:
            if not interpolate_splines:
                b = self.before
                return Sample(list(b.positions), list(b.velocities), list(b.accelerations),
                              False)
            return interpolate(self.before_ns, self.before, t_first, first, t_ns)
        for i in range(len(self.points) - 1):
            a, b = self.points[i], self.points[i + 1]
            t0, t1 = self.start_ns + a.time_ns, self.start_ns + b.time_ns
            if t0 <= t_ns < t1:
                if not interpolate_splines:
                    return Sample(list(b.positions), _or_zeros(b.velocities, b),
                                  _or_zeros(b.accelerations, b), False)
                return interpolate(t0, a, t1, b, t_ns)
        last = self.points[-1]
        return Sample(list(last.positions), _or_zeros(last.velocities, last),
                      _or_zeros(last.accelerations, last), past_end=True)


def _or_zeros(values: list[float], point: Point) -> list[float]:
    return list(values) if values else [0.0] * len(point.positions)
