"""The schedule: who acts when, in which order, and which producer sample each input consumes."""

import math
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plan.schedule import (
    DELAYED,
    PIPELINE_WINDOW,
    SAME_TICK,
    CycleError,
    Edge,
    Schedule,
    find_same_tick_cycle,
)
from plan.timeutil import NS_PER_S

BOUNDED = settings(max_examples=100, deadline=None)


def nav_schedule(last_tick: int = 100) -> Schedule:
    """physics every tick, sensors every 2, control every 5; control -> physics is delayed."""
    edges = [
        Edge("sensors", "physics", "/odom", SAME_TICK),
        Edge("control", "sensors", "/scan", SAME_TICK),
        Edge("control", "physics", "/odom", SAME_TICK),
        Edge("physics", "control", "/cmd_vel", DELAYED),
    ]
    return Schedule(10_000_000, last_tick, {"physics": 1, "sensors": 2, "control": 5}, edges)


# ---------------------------------------------------------------- unit tests


def test_due_order_and_periods():
    s = nav_schedule()
    assert s.due(0) == ("physics", "sensors", "control")
    assert s.due(1) == ("physics",)
    assert s.due(2) == ("physics", "sensors")
    assert s.due(5) == ("physics", "control")
    assert s.due(10) == ("physics", "sensors", "control")
    assert s.hyperperiod == 10
    assert s.n_ticks == 101
    assert s.activations("control") == 21
    assert s.activations("sensors") == 51
    assert s.is_due("sensors", 4) and not s.is_due("sensors", 5)


def test_time_is_integer_nanoseconds():
    s = nav_schedule()
    assert s.time_ns(3) == 30_000_000
    assert type(s.time_ns(3)) is int
    assert s.time_ns(10**12) == 10**19  # no float rounding, however long the run


def test_ros_sensor_rates_count_in_ticks_of_a_150th_of_a_second():
    """Camera 30 Hz, lidar 15 Hz, physics 50 Hz: every 5th, 10th and 3rd tick of 1/150 s;
    each tick's time rounded to whole ns once, every period exact in ticks."""
    edges = [Edge("camera", "physics", "/cosim/world_state", SAME_TICK),
             Edge("lidar", "physics", "/cosim/world_state", SAME_TICK)]
    s = Schedule(Fraction(NS_PER_S, 150), 300, {"physics": 3, "camera": 5, "lidar": 10}, edges)
    assert s.due(0) == ("physics", "camera", "lidar")
    assert s.due(5) == ("camera",) and s.due(15) == ("physics", "camera")
    assert [s.time_ns(k) for k in (0, 1, 2, 3, 5, 10, 150, 300)] == [
        0, 6_666_667, 13_333_333, 20_000_000, 33_333_333, 66_666_667, NS_PER_S, 2 * NS_PER_S]
    assert all(type(s.time_ns(k)) is int for k in range(301))
    assert [s.tick_at(s.time_ns(k)) for k in range(301)] == list(range(301))
    assert s.input_tick(edges[0], 5) == 3  # the camera at 1/30 s renders physics at 20 ms
    assert s.activations("camera") == 61 and s.activations("lidar") == 31


def test_input_ticks_same_tick_and_delayed():
    s = nav_schedule()
    odom_to_control, scan, odom_to_sensors, cmd = (
        s.edges[2], s.edges[1], s.edges[0], s.edges[3])
    assert s.input_tick(odom_to_sensors, 4) == 4
    assert s.input_tick(scan, 5) == 4  # sensors last acted at 4: sample and hold
    assert s.input_tick(odom_to_control, 5) == 5
    assert s.input_tick(cmd, 0) is None  # no command yet at the first tick
    assert s.input_tick(cmd, 1) == 0
    assert s.input_tick(cmd, 5) == 0  # control acts at 5, so physics at 5 still holds 0
    assert s.input_tick(cmd, 6) == 5


def test_inputs_of_and_history_depth():
    s = nav_schedule()
    assert [e.topic for e in s.inputs_of["control"]] == ["/scan", "/odom"]
    assert s.inputs_of["physics"][0].mode == DELAYED
    # control holds up to 5 physics samples; physics may run the pipeline window ahead
    assert s.history_depth(s.edges[2]) == 2 * 5 + 64 + PIPELINE_WINDOW


def test_cycle_named():
    edges = [Edge("b", "a", "/a", SAME_TICK), Edge("a", "b", "/b", SAME_TICK)]
    with pytest.raises(CycleError) as info:
        Schedule(1, 10, {"a": 1, "b": 1}, edges)
    assert str(info.value) == "a -> b -> a"
    assert info.value.cycle == ["a", "b", "a"]


def test_self_loop_is_a_cycle_and_delay_breaks_it():
    assert find_same_tick_cycle(["a"], [Edge("a", "a", "/a", SAME_TICK)]) == ["a", "a"]
    assert find_same_tick_cycle(["a"], [Edge("a", "a", "/a", DELAYED)]) is None
    edges = [Edge("b", "a", "/a", SAME_TICK), Edge("a", "b", "/b", DELAYED)]
    s = Schedule(1, 10, {"a": 1, "b": 1}, edges)
    assert s.due(0) == ("a", "b")


def test_long_chain_has_no_recursion_limit():
    n = 5000
    names = [f"n{i:05d}" for i in range(n)]
    edges = [Edge(names[i + 1], names[i], f"/t{i}", SAME_TICK) for i in range(n - 1)]
    assert find_same_tick_cycle(names, edges) is None
    edges.append(Edge(names[0], names[-1], "/back", SAME_TICK))
    cycle = find_same_tick_cycle(names, edges)
    assert cycle is not None and len(cycle) == n + 1


@pytest.mark.parametrize(("tick_ns", "last_tick", "periods", "words"), [
    (0, 10, {"a": 1}, "tick_ns"),
    (1.0, 10, {"a": 1}, "tick_ns"),
    (Fraction(-1, 3), 10, {"a": 1}, "tick_ns"),
    (10, -1, {"a": 1}, "last_tick"),
    (10, 2.0, {"a": 1}, "last_tick"),
    (10, 10, {"a": 0}, "period of a"),
    (10, 10, {"a": 1.5}, "period of a"),
    (10, 10, {"a": True}, "period of a"),
])
def test_bad_arguments_refused(tick_ns, last_tick, periods, words):
    with pytest.raises(ValueError, match=words):
        Schedule(tick_ns, last_tick, periods, [])


def test_edge_to_unknown_node_or_mode_refused():
    with pytest.raises(ValueError, match="no period"):
        Schedule(1, 1, {"a": 1}, [Edge("a", "ghost", "/g", DELAYED)])
    with pytest.raises(ValueError, match="unknown node"):
        find_same_tick_cycle(["a"], [Edge("a", "ghost", "/g", SAME_TICK)])
    with pytest.raises(ValueError, match="mode"):
        Schedule(1, 1, {"a": 1, "b": 1}, [Edge("a", "b", "/b", "sometimes")])


def test_large_hyperperiod_without_table():
    periods = {"a": 997, "b": 991, "c": 983}  # lcm far above the table limit
    s = Schedule(1, 10, periods, [Edge("b", "a", "/a", SAME_TICK)])
    assert s.hyperperiod == 997 * 991 * 983
    assert s.due(0) == ("a", "b", "c")
    assert s.due(997 * 991) == ("a", "b")
    assert s.due(983) == ("c",)


# ---------------------------------------------------------------- property tests


@st.composite
def dag_schedules(draw, max_nodes: int = 6):
    """Random periods (1..12 ticks) and edges: same_tick only forward, delayed anywhere."""
    n = draw(st.integers(1, max_nodes))
    # Names are shuffled against the DAG order so the tie-break by name is exercised.
    names = draw(st.permutations([f"n{i}" for i in range(n)]))
    periods = {name: draw(st.integers(1, 12)) for name in names}
    edges = []
    for i in range(n):
        for j in range(n):
            mode = draw(st.sampled_from([None, None, SAME_TICK, DELAYED]))
            if mode is None or (mode == SAME_TICK and i >= j):
                continue
            edges.append(Edge(names[j], names[i], f"/{names[i]}", mode))
    last_tick = draw(st.integers(0, 60))
    return Schedule(draw(st.integers(1, 10**7)), last_tick, periods, edges)


def consumer_ticks(s: Schedule, edge: Edge, limit: int = 80):
    return [k for k in range(limit) if s.is_due(edge.consumer, k)]


@BOUNDED
@given(dag_schedules())
def test_inputs_never_from_the_future_and_sample_and_hold(s):
    for edge in s.edges:
        for k in consumer_ticks(s, edge):
            t = s.input_tick(edge, k)
            if edge.mode == DELAYED and k == 0:
                assert t is None
                continue
            assert type(t) is int
            if edge.mode == SAME_TICK:
                assert 0 <= t <= k
            else:
                assert 0 <= t < k
            assert s.is_due(edge.producer, t)
            # the latest such tick: the producer is not due in between
            end = k + 1 if edge.mode == SAME_TICK else k
            assert not any(s.is_due(edge.producer, u) for u in range(t + 1, end))


@BOUNDED
@given(dag_schedules())
def test_schedule_repeats_with_the_hyperperiod(s):
    h = s.hyperperiod
    assert h == math.lcm(*s.periods.values())
    assert type(h) is int
    for k in range(min(h, 60)):
        assert s.due(k) == s.due(k + h) == s.due(k + 7 * h)
        assert set(s.due(k)) == {n for n, p in s.periods.items() if k % p == 0}
        for edge in s.edges:
            if s.is_due(edge.consumer, k) and not (edge.mode == DELAYED and k == 0):
                t, t2 = s.input_tick(edge, k), s.input_tick(edge, k + h)
                assert t2 - t == h


@BOUNDED
@given(dag_schedules())
def test_producers_precede_same_tick_consumers(s):
    assert sorted(s.order) == sorted(s.periods)
    for k in range(min(s.hyperperiod, 60)):
        due = s.due(k)
        assert len(set(due)) == len(due)
        for edge in s.edges:
            if edge.mode == SAME_TICK and edge.consumer in due and edge.producer in due:
                assert due.index(edge.producer) < due.index(edge.consumer)


@BOUNDED
@given(dag_schedules())
def test_every_time_value_is_an_int(s):
    for value in (s.tick_ns, s.last_tick, s.n_ticks, s.hyperperiod):
        assert type(value) is int
    for k in (0, 1, s.last_tick, s.last_tick + s.hyperperiod):
        assert type(s.time_ns(k)) is int
        assert s.time_ns(k) == k * s.tick_ns
    for node in s.periods:
        assert type(s.activations(node)) is int
        assert s.activations(node) == len(
            [k for k in range(s.n_ticks) if s.is_due(node, k)])
    for edge in s.edges:
        assert type(s.history_depth(edge)) is int
        for k in range(1, 30):
            assert type(s.input_tick(edge, k)) is int


@st.composite
def cyclic_graphs(draw, max_nodes: int = 7):
    """A random graph with at least one same_tick cycle, plus random other edges."""
    n = draw(st.integers(1, max_nodes))
    names = [f"n{i}" for i in range(n)]
    loop = draw(st.permutations(names))[: draw(st.integers(1, n))]
    edges = [Edge(loop[(i + 1) % len(loop)], loop[i], f"/{loop[i]}", SAME_TICK)
             for i in range(len(loop))]
    for _ in range(draw(st.integers(0, 2 * n))):
        producer, consumer = draw(st.sampled_from(names)), draw(st.sampled_from(names))
        edges.append(Edge(consumer, producer, f"/{producer}",
                          draw(st.sampled_from([SAME_TICK, DELAYED]))))
    edges = draw(st.permutations(edges))
    return names, {name: draw(st.integers(1, 12)) for name in names}, edges


@BOUNDED
@given(cyclic_graphs())
def test_same_tick_cycles_raise_naming_a_real_cycle(graph):
    names, periods, edges = graph
    with pytest.raises(CycleError) as info:
        Schedule(1, 10, periods, edges)
    cycle = info.value.cycle
    assert cycle[0] == cycle[-1]
    assert len(set(cycle[:-1])) == len(cycle) - 1  # a simple cycle
    same_tick = {(e.producer, e.consumer) for e in edges if e.mode == SAME_TICK}
    for producer, consumer in zip(cycle, cycle[1:], strict=False):
        assert (producer, consumer) in same_tick
    assert str(info.value) == " -> ".join(cycle)


@BOUNDED
@given(dag_schedules())
def test_delayed_edges_never_make_a_cycle(s):
    assert find_same_tick_cycle(list(s.periods), s.edges) is None
    # turning every edge delayed keeps it acyclic whatever the direction
    flipped = [Edge(e.producer, e.consumer, e.topic, DELAYED) for e in s.edges]
    assert find_same_tick_cycle(list(s.periods), flipped) is None


@BOUNDED
@given(st.integers(1, 7), st.integers(0, 40), st.one_of(st.none(), st.integers(0, 45)))
def test_a_windowed_nodes_activations_up_to_any_tick_are_counted_once(period, start, end):
    """Schedule.activations(node, until=) and first_activation: the one count of a windowed
    node's activations (the manifest's, the plan's latched outputs', the samples')."""
    from plan.schedule import first_activation

    s = Schedule(1, 40, {"a": 1, "n": period}, [Edge("n", "a", "/t", SAME_TICK)],
                 {"n": (start, end)})
    due = [k for k in range(s.n_ticks) if s.is_due("n", k)]
    assert s.first_activation("n", start) == first_activation(period, start)
    assert not due or due[0] == first_activation(period, start)
    for until in range(s.n_ticks + 3):
        assert s.activations("n", until=until) == len([k for k in due if k < until])
    assert s.activations("n") == len(due)
