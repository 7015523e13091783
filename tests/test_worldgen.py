"""bench.worldgen: seeded worlds that load, with starts and goals clear of obstacles and a way
between them, checked against the project's own geometry (an independent reading of the
compiled MJCF); and one of them driven in-process to its goal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.free_space import FreeSpace, Shape
from bench.worldgen import CLEARANCE, DOOR, FAMILIES, generate, robot_radius
from descriptions.load import load_scenario
from descriptions.world_geometry import static_obstacles
from descriptions.worldfile import load_world_model
from orchestrator.api import run


@pytest.mark.parametrize("seed", range(len(FAMILIES)))  # one world of each family
def test_a_generated_world_loads_with_a_clear_start_goal_and_way(tmp_path, seed):
    world = generate(seed)
    assert world.family == FAMILIES[seed] and world == generate(seed)
    scenario = load_scenario(world.write(tmp_path))  # the load-time checks pass
    assert scenario.warnings == []  # the controller's map joins start and goal too
    assert "camera" not in scenario.nodes and scenario.model.seed == seed
    obstacles = static_obstacles(load_world_model(scenario.world))
    assert len(obstacles) == len(world.shapes)
    for x, y, _ in (world.start, world.goal):
        assert min(o.distance(x, y) for o in obstacles) >= CLEARANCE
    assert 4.0 <= world.trip < math.inf


def test_the_families_differ_and_seeds_differ():
    worlds = [generate(seed) for seed in range(2 * len(FAMILIES))]
    assert [w.family for w in worlds] == list(FAMILIES) * 2
    assert len({(w.shapes, w.start, w.goal) for w in worlds}) == len(worlds)
    assert sum(w.family == "forest_dense" for w in worlds) == 2
    trees = {w.family: sum(s.kind == "cylinder" for s in w.shapes) for w in worlds[:3]}
    assert trees["forest_sparse"] < trees["forest_medium"] < trees["forest_dense"]


def test_doors_between_rooms_are_0_8_to_1_2_m_wide():
    widths = []
    for seed in range(5, 5 + 6 * len(FAMILIES), len(FAMILIES)):
        pieces = {s.name: s for s in generate(seed).shapes if s.name.startswith("room_")}
        for name, first in pieces.items():
            second = pieces.get(name[:-1] + "1")
            if name.endswith("_0") and second:
                gap = (math.hypot(second.x - first.x, second.y - first.y)
                       - max(first.hx, first.hy) - max(second.hx, second.hy))
                widths.append(gap)
    assert len(widths) > 10
    assert DOOR[0] - 1e-9 <= min(widths) and max(widths) <= DOOR[1] + 1e-9


def test_the_shapes_distance_agrees_with_the_compiled_world(tmp_path):
    world = generate(5)  # rooms: turned boxes and walls
    obstacles = {o.name: o for o in static_obstacles(load_world_model(
        load_scenario(world.write(tmp_path)).world))}
    points = np.random.default_rng(0).uniform(-4.2, 4.2, size=(200, 2))
    for shape in world.shapes:
        ours = shape.distance(points[:, 0], points[:, 1])
        theirs = [obstacles[shape.name].distance(x, y) for x, y in points]
        assert np.allclose(ours, theirs, atol=2e-3), shape.name


def test_the_grid_search_needs_a_gap_wider_than_the_robot():
    def wall_with_gap(gap: float) -> list[Shape]:
        half = (8.0 - gap) / 4
        return [Shape("a", "box", -gap / 2 - half, 0.0, half, 0.05),
                Shape("b", "box", gap / 2 + half, 0.0, half, 0.05)]

    radius = robot_radius()
    narrow = FreeSpace(wall_with_gap(2 * radius - 0.02), 4.0, radius)
    wide = FreeSpace(wall_with_gap(2 * radius + 0.1), 4.0, radius)
    assert narrow.path_length((0.0, -2.0), (0.0, 2.0)) == math.inf
    assert 4.0 <= wide.path_length((0.0, -2.0), (0.0, 2.0)) < 4.2


def test_the_controller_drives_a_generated_world_to_its_goal(tmp_path):
    world = generate(5)  # rooms joined by doors
    result = run(world.write(tmp_path / "world"), in_process=True, out=tmp_path / "runs",
                 picture=False)
    assert result.success, result.summary()
    assert result.metrics["collisions"] == 0 and result.notes == []
