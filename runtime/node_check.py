"""``check_node``: run a step class through cosim's rules before it joins a scenario, as
Gymnasium's ``check_env`` does for an environment, and name every rule it breaks.

The node is reset and stepped a few times on the inputs it is given (by default a default
message of each type it declares in ``input_types``), three times over: two fresh
instances reset with the same seed, then the first one reset again (as a restart does).
Each activation is watched: the clocks and sleeps it calls (``sys.setprofile`` sees every
call of a built-in function, however it was imported), whether it drew from the global
``random`` or numpy generators (their states before and after) or from the OS's entropy
(``os.urandom``: an unseeded ``np.random.default_rng()``, ``random.SystemRandom``,
``uuid4``). Then the named checks of ``NODE_CHECKS`` judge what was seen. Threads the node
starts itself are not watched.
"""

from __future__ import annotations

import datetime
import gc
import os
import random
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import BuiltinFunctionType, BuiltinMethodType
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from nodes.contract import NodeConfig, StepNode, Tick, take_output_marks
from plan.timeutil import rate_to_period_ns, tick_time_ns
from runtime.cdr.decode import decode
from runtime.cdr.encode import encode
from runtime.message_diff import serialized_difference

CLOCKS = {id(f): f"time.{f.__name__}" for f in (
    time.time, time.time_ns, time.monotonic, time.monotonic_ns, time.perf_counter,
    time.perf_counter_ns, time.process_time, time.process_time_ns, time.thread_time,
    time.thread_time_ns, time.clock_gettime, time.clock_gettime_ns)}
"""The built-in functions that read a clock, by id (what the profiler is given)."""
DATE_NOW = frozenset({"now", "utcnow", "today"})
SLEEPS = {id(time.sleep): "time.sleep"}
ENTROPY = {id(os.urandom): "os.urandom", id(os.getrandom): "os.getrandom"} \
    if hasattr(os, "getrandom") else {id(os.urandom): "os.urandom"}


class NodeCheckError(AssertionError):
    """A step class broke cosim's rules: ``report`` (a ``NodeCheckReport``) says which and
    why, and so does the message."""

    def __init__(self, report: NodeCheckReport):
        super().__init__(str(report))
        self.report = report


@dataclass
class Watched:
    """What one call of reset or step did besides returning: clocks read, sleeps, draws
    from global or OS randomness (name -> calls), and what went wrong ('raised ...')."""

    clocks: Counter = field(default_factory=Counter)
    sleeps: Counter = field(default_factory=Counter)
    randomness: Counter = field(default_factory=Counter)
    error: str | None = None


@dataclass
class Activation:
    """One step: its tick, what it returned (own topic -> message), the serialised
    messages of its declared topics, and what was watched."""

    tick: Tick
    outputs: dict[str, Any]
    serialised: dict[str, bytes]
    watched: Watched
    encode_errors: dict[str, str] = field(default_factory=dict)


@dataclass
class Episode:
    """A reset and the steps after it, until the last step or the first that raised."""

    label: str
    reset: Watched
    steps: list[Activation] = field(default_factory=list)

    def where(self, index: int | None) -> str:
        """'reset' or 'step at tick 3' (and which run, for the later ones)."""
        what = "reset" if index is None else f"step at tick {self.steps[index].tick.index}"
        return what if self.label == "first" else f"{what} ({self.label})"

    def calls(self) -> list[tuple[str, Watched]]:
        """(where, watched) of the reset and every step."""
        return [(self.where(None), self.reset)] + [
            (self.where(i), a.watched) for i, a in enumerate(self.steps)]


@dataclass
class Trial:
    """Everything the checks judge: the class, its checked parameters, the topics it
    declares (own names -> classes) and the three episodes."""

    node_class: type
    params: BaseModel
    outputs: dict[str, type]
    latched: dict[str, type]
    seed: int
    episodes: dict[str, Episode]


@dataclass(frozen=True)
class NodeCheck:
    """A named check of ``check_node``: ``judge(trial)`` gives its problems (none: passed);
    ``doc`` says what it holds."""

    name: str
    judge: Callable[[Trial], list[str]]

    @property
    def doc(self) -> str:
        """The check's docstring, first paragraph, on one line."""
        return " ".join((self.judge.__doc__ or "").strip().split("\n\n")[0].split())


@dataclass(frozen=True)
class CheckResult:
    """One check's verdict: its name, what it holds and its problems (none: passed)."""

    name: str
    doc: str
    problems: tuple[str, ...]
    ran: bool = True  # False: the node could not be set up, so nothing was judged

    @property
    def passed(self) -> bool:
        """Whether the check ran and found nothing wrong."""
        return self.ran and not self.problems


@dataclass(frozen=True)
class NodeCheckReport:
    """What ``check_node`` found: every check's result, in ``NODE_CHECKS`` order."""

    node: str
    results: tuple[CheckResult, ...]

    @property
    def passed(self) -> bool:
        """Whether every check passed."""
        return all(r.passed for r in self.results)

    @property
    def failures(self) -> dict[str, tuple[str, ...]]:
        """Failed check name -> its problems (checks that did not run are not in it)."""
        return {r.name: r.problems for r in self.results if r.problems}

    def __str__(self) -> str:
        failed = [r for r in self.results if r.problems]
        if not failed:
            return f"check_node({self.node}): all {len(self.results)} checks passed"
        lines = [f"check_node({self.node}): {len(failed)} of {len(self.results)} checks failed"]
        for r in failed:
            lines.append(f"  {r.name}: {r.doc}")
            lines += ["    - " + problem.replace("\n", "\n      ") for problem in r.problems]
        for label, names in (("passed", [r.name for r in self.results if r.passed]),
                             ("not run", [r.name for r in self.results if not r.ran])):
            if names:
                lines.append(f"  {label}: {', '.join(names)}")
        return "\n".join(lines)


NODE_CHECKS: list[NodeCheck] = []
"""The checks of ``check_node``, in the order they are reported."""


def node_check(judge: Callable[[Trial], list[str]]) -> Callable[[Trial], list[str]]:
    """Register ``judge`` as a check of ``check_node``, named after the function."""
    NODE_CHECKS.append(NodeCheck(judge.__name__, judge))
    return judge


def check_node(node_class: type, params: BaseModel | Mapping[str, Any] | None = None, *,
               world: str | Path | None = None, goal: Mapping[str, float] | None = None,
               inputs: Mapping[str, Any] | Callable[[Tick], Mapping[str, Any]] | None = None,
               seed: int = 0, steps: int = 3, rate: float | str = 50,
               tick_rate: float | str | None = None, name: str = "node",
               joint_goal: Mapping[str, Any] | None = None,
               scenario_dir: str | Path | None = None, check: bool = True) -> NodeCheckReport:
    """Run the step class ``node_class`` through cosim's rules and name what it breaks.

    ``params`` are the node's parameters (a dict as in a scenario's ``params:``, or an
    instance of its ``Params``); ``world`` (an MJCF file), ``goal`` and ``joint_goal`` are
    what a scenario would give it. The node is stepped ``steps`` times at ``rate`` Hz (on
    a tick of ``tick_rate`` Hz, default the node's rate) on ``inputs``: own input topic ->
    message, given at every step; or a function of the Tick giving that mapping (called
    once per step; leave a topic out where it has no sample, as a delayed input at the
    first tick); by default a default message of each type the node declares in
    ``input_types``. Each step gets its own copy, through CDR as a transport delivers.

    The checks (``NODE_CHECKS``, each named, each with a docstring): valid parameters, no
    exception, only the declared topics of the declared types, latched outputs at the first
    step only, no wall clock, no sleep, no unseeded or global randomness, the same seed
    gives the same serialised outputs (two instances), and a reset replays them.

    Returns the ``NodeCheckReport`` when every check passes; raises ``NodeCheckError``
    (an AssertionError whose ``report`` lists each failing check with its reasons) when one
    fails, or with ``check=False`` returns the report either way.
    """
    label = getattr(node_class, "__name__", repr(node_class))
    trial_or_problems = _trial(node_class, params, world, goal, inputs, seed, steps, rate,
                               tick_rate, name, joint_goal, scenario_dir)
    if isinstance(trial_or_problems, Trial):
        results = tuple(CheckResult(c.name, c.doc, tuple(c.judge(trial_or_problems)))
                        for c in NODE_CHECKS)
    else:
        results = tuple(CheckResult(c.name, c.doc, tuple(trial_or_problems))
                        if c.name == "valid_setup" else CheckResult(c.name, c.doc, (), False)
                        for c in NODE_CHECKS)
    report = NodeCheckReport(label, results)
    if check and not report.passed:
        raise NodeCheckError(report)
    return report


def _trial(node_class, params, world, goal, inputs, seed, steps, rate, tick_rate, name,
           joint_goal, scenario_dir) -> Trial | list[str]:
    """Set up and run the three episodes; the setup's problems when it cannot."""
    if not (isinstance(node_class, type) and issubclass(node_class, StepNode)):
        return [f"{node_class!r} is not a subclass of nodes.contract.StepNode"]
    try:
        checked = params if isinstance(params, BaseModel) else \
            node_class.Params(**dict(params or {}))
    except ValidationError as exc:
        return [f"the parameters do not fit {node_class.__name__}.Params: {exc}"]
    if node_class.needs_world and world is None:
        return [f"{node_class.__name__} needs a world (needs_world): give world=PATH"]
    try:
        period_ns = rate_to_period_ns(rate)
        tick_ns = period_ns if tick_rate is None else rate_to_period_ns(tick_rate)
    except ValueError as exc:
        return [f"rate {rate!r} / tick_rate {tick_rate!r}: {exc}"]
    if period_ns % tick_ns:
        return [f"the period of rate {rate} is not a whole number of ticks of {tick_rate}"]
    try:
        outputs = dict(node_class.outputs(checked))
        latched = dict(node_class.latched_outputs(checked))
    except Exception as exc:  # noqa: BLE001 - a user's class: any failure is the report
        return [f"outputs()/latched_outputs() raised {_error(exc)}"]
    config = NodeConfig(name=name, params=checked, tick_ns=tick_ns, period_ns=period_ns,
                        world=Path(world) if world is not None else None,
                        goal=dict(goal) if goal is not None else None,
                        joint_goal=dict(joint_goal) if joint_goal is not None else None,
                        scenario_dir=Path(scenario_dir or Path.cwd()).resolve(),
                        render_warm_up=False)
    per = int(period_ns // tick_ns)
    ticks = [Tick(k * per, tick_time_ns(k * per, tick_ns)) for k in range(max(steps, 2))]
    try:
        feed = _feed(node_class, checked, inputs, ticks)
    except Exception as exc:  # noqa: BLE001 - the inputs are the user's too
        return [f"the inputs could not be made: {_error(exc)}"]
    first = node_class()
    episodes = {"first": _episode("first", first, seed, config, ticks, feed, outputs, latched),
                "second": _episode("a second instance, same seed", node_class(), seed, config,
                                   ticks, feed, outputs, latched),
                "reset": _episode("the first instance reset again", first, seed, config,
                                  ticks, feed, outputs, latched)}
    return Trial(node_class, checked, outputs, latched, seed, episodes)


def _feed(node_class, params, inputs, ticks) -> list[dict[str, tuple[type, bytes]]]:
    """Per tick, own input topic -> (class, CDR bytes): what each step is given a copy of."""
    if inputs is None:
        defaults = {topic: cls() for topic, cls in node_class.input_types(params).items()}
        inputs = defaults
    per_tick = [dict(inputs(tick) if callable(inputs) else inputs) for tick in ticks]
    return [{topic: (type(msg), encode(msg)) for topic, msg in given.items() if msg is not None}
            for given in per_tick]


def _episode(label, node, seed, config, ticks, feed, outputs, latched) -> Episode:
    """Reset ``node`` and step it on ``feed`` until the end or the first step that raises."""
    watched, _ = _watch(lambda: node.reset(seed, config))
    episode = Episode(label, watched)
    if watched.error is not None:
        return episode
    declared = {**outputs, **latched}
    for tick, given in zip(ticks, feed, strict=True):
        copies = {topic: decode(data, cls) for topic, (cls, data) in given.items()}
        watched, returned = _watch(lambda t=tick, c=copies: node.step(t, c))
        take_output_marks()  # encoded here without them
        node.take_notes()
        if not isinstance(returned, dict) and watched.error is None:
            watched.error = (f"returned {type(returned).__name__}, not a dict of topic -> "
                             "message")
        returned = returned if isinstance(returned, dict) else {}
        serialised, encode_errors = {}, {}
        for topic, msg in returned.items():
            if topic in declared and isinstance(msg, declared[topic]):
                try:
                    serialised[topic] = encode(msg)
                except Exception as exc:  # noqa: BLE001 - reported by declared_types
                    encode_errors[topic] = _error(exc)
        episode.steps.append(Activation(tick, returned, serialised, watched, encode_errors))
        if watched.error is not None:
            break
    return episode


def _watch(call: Callable[[], Any]) -> tuple[Watched, Any]:
    """Run ``call`` under the profiler and the global generators' watch."""
    watched = Watched()

    def profile(frame, event, arg):
        if event != "c_call":
            return
        key = id(arg)
        if key in CLOCKS:
            watched.clocks[CLOCKS[key]] += 1
        elif key in SLEEPS:
            watched.sleeps[SLEEPS[key]] += 1
        elif key in ENTROPY:
            watched.randomness[f"{ENTROPY[key]} (OS entropy: an unseeded generator)"] += 1
        elif isinstance(arg, BuiltinMethodType | BuiltinFunctionType) and \
                arg.__name__ in DATE_NOW and isinstance(arg.__self__, type) and \
                issubclass(arg.__self__, datetime.date):
            watched.clocks[f"{arg.__self__.__name__}.{arg.__name__}"] += 1

    before_random, before_numpy = random.getstate(), np.random.get_state(legacy=False)
    previous = sys.getprofile()
    result = None
    # Garbage the process made before (another test's objects, a library's) is collected
    # now, not inside the call: finalizers and gc callbacks that a collection runs on this
    # thread read clocks too, and were blamed on the node's step.
    gc.collect()
    collecting = gc.isenabled()
    gc.disable()
    sys.setprofile(profile)
    try:
        result = call()
    except Exception as exc:  # noqa: BLE001 - a user's node: any failure is the report
        watched.error = "raised " + _error(exc, traceback.extract_tb(exc.__traceback__)[-1:])
    finally:
        sys.setprofile(previous)
        if collecting:
            gc.enable()
    if random.getstate() != before_random:
        watched.randomness["the global random module (random.random(), random.randint(), "
                           "...)"] += 1
    after_numpy = np.random.get_state(legacy=False)
    if _numpy_state_key(after_numpy) != _numpy_state_key(before_numpy):
        watched.randomness["numpy's global generator (np.random.rand(), np.random.normal(), "
                           "...)"] += 1
    return watched, result


def _numpy_state_key(state: dict) -> tuple:
    """numpy's global generator state as a comparable value."""
    inner = state["state"]
    return (inner["key"].tobytes(), int(inner["pos"]), state["has_gauss"], state["gauss"])


def _error(exc: BaseException, frames: list | None = None) -> str:
    """'ValueError: text (file.py:12)'."""
    where = f" ({Path(frames[0].filename).name}:{frames[0].lineno})" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"


# -- the checks ---------------------------------------------------------------------------

@node_check
def valid_setup(trial: Trial) -> list[str]:
    """The class is a StepNode, its parameters fit its Params, it has the world it needs
    and its inputs can be made."""
    return []  # a setup that fails makes no trial: check_node puts its problems here


@node_check
def no_exception(trial: Trial) -> list[str]:
    """reset and every step return without raising (step: a dict of topic -> message)."""
    problems, seen = [], set()
    for episode in trial.episodes.values():
        for where, watched in episode.calls():
            if watched.error is not None and watched.error not in seen:
                seen.add(watched.error)  # the same failure in every episode: say it once
                problems.append(f"{where} {watched.error}")
    return problems


@node_check
def declared_topics(trial: Trial) -> list[str]:
    """Every step returns a message on each topic of outputs() and on no undeclared topic."""
    problems = []
    episode = trial.episodes["first"]
    for i, act in enumerate(episode.steps):
        if act.watched.error is not None:
            continue
        undeclared = sorted(set(act.outputs) - set(trial.outputs) - set(trial.latched))
        missing = sorted(set(trial.outputs) - set(act.outputs))
        if undeclared:
            problems.append(f"{episode.where(i)} published {', '.join(undeclared)}, not "
                            "declared in outputs() or latched_outputs()")
        if missing:
            problems.append(f"{episode.where(i)} left out {', '.join(missing)} (declared in "
                            "outputs(): due at every step)")
    return problems


@node_check
def declared_types(trial: Trial) -> list[str]:
    """Each message is of the class its topic declares, and serialises."""
    problems = []
    declared = {**trial.outputs, **trial.latched}
    episode = trial.episodes["first"]
    for i, act in enumerate(episode.steps):
        for topic, msg in act.outputs.items():
            if topic in declared and not isinstance(msg, declared[topic]):
                problems.append(f"{episode.where(i)} returned {type(msg).__name__} on {topic}, "
                                f"declared {declared[topic].__name__}")
        problems += [f"{episode.where(i)}: {topic} does not serialise: {why}"
                     for topic, why in act.encode_errors.items()]
    return problems


@node_check
def latched_first_step(trial: Trial) -> list[str]:
    """Latched outputs come with the first step after each reset, and never again."""
    problems = []
    for episode in (trial.episodes["first"], trial.episodes["reset"]):
        for i, act in enumerate(episode.steps):
            given = sorted(set(act.outputs) & set(trial.latched))
            if i == 0 and act.watched.error is None:
                missing = sorted(set(trial.latched) - set(given))
                if missing:
                    problems.append(f"{episode.where(i)} left out latched {', '.join(missing)} "
                                    "(due at the first step after each reset)")
            elif i > 0 and given:
                problems.append(f"{episode.where(i)} published latched {', '.join(given)} "
                                "again (latched outputs go out at the first step only)")
    return problems


@node_check
def no_wall_clock(trial: Trial) -> list[str]:
    """reset and step read no clock (time.time, time.monotonic, perf_counter, datetime.now,
    ...): a node's time is the Tick it is given."""
    return _calls(trial, "clocks", "read the wall clock")


@node_check
def no_sleep(trial: Trial) -> list[str]:
    """reset and step never sleep: the runtime decides when a node runs."""
    return _calls(trial, "sleeps", "slept")


@node_check
def no_unseeded_random(trial: Trial) -> list[str]:
    """Random numbers come from self.rng (seeded from the scenario seed and the node name),
    not from the global random or numpy generators or the OS's entropy."""
    return _calls(trial, "randomness", "drew random numbers from")


@node_check
def same_seed_same_outputs(trial: Trial) -> list[str]:
    """Two instances reset with the same seed publish the same bytes at every step."""
    return _compare(trial.episodes["first"], trial.episodes["second"])


@node_check
def reset_replays(trial: Trial) -> list[str]:
    """Reset again with the same seed (as a restart does), a node publishes what it
    published the first time: no state survives a reset."""
    return _compare(trial.episodes["first"], trial.episodes["reset"])


def _calls(trial: Trial, kind: str, verb: str) -> list[str]:
    """One problem per kind of call of ``kind`` ('time.time_ns'), naming the resets and
    steps that made it (of any episode: the same one in each is said once)."""
    where: dict[str, list[str]] = {}
    for episode in trial.episodes.values():
        for i in [None, *range(len(episode.steps))]:
            watched = episode.reset if i is None else episode.steps[i].watched
            for what in getattr(watched, kind):
                at = "reset" if i is None else str(episode.steps[i].tick.index)
                if at not in where.setdefault(what, []):
                    where[what].append(at)
    problems = []
    for what, places in where.items():
        ticks = [p for p in places if p != "reset"]
        parts = (["reset"] if "reset" in places else []) + (
            [f"the step{'s' if len(ticks) > 1 else ''} at tick{'s' if len(ticks) > 1 else ''} "
             f"{', '.join(ticks)}"] if ticks else [])
        problems.append(f"{' and '.join(parts)} {verb} {what}")
    return problems


def _compare(first: Episode, other: Episode) -> list[str]:
    """The first step and topic where ``other`` published other bytes than ``first``,
    naming the first field that differs with both values."""
    for a, b in zip(first.steps, other.steps, strict=False):
        for topic in sorted(set(a.serialised) | set(b.serialised)):
            x, y = a.serialised.get(topic), b.serialised.get(topic)
            if x == y:
                continue
            where = f"at tick {a.tick.index}, {topic}"
            if x is None or y is None:
                return [f"{where} is published in one run and not in the other "
                        f"({other.label})"]
            found = serialized_difference(x, y, type(a.outputs[topic]))
            what = found.describe() if found else "the bytes differ"
            return [f"{where} differs ({other.label}): {what}"]
    if len(first.steps) != len(other.steps):
        return [f"{other.label} stepped {len(other.steps)} times, the first "
                f"{len(first.steps)} (a step raised in one of them)"]
    return []
