"""How to run a checked scenario: run options and transport settings, passed explicitly.

Nothing here changes what a run computes (the digest is the same whatever the options);
they choose how the work is done: pipelined or strictly in lockstep, forked or fresh
node processes, zenoh shared memory, the camera's GL warm-up, profiling, a pace on the
wall clock (``real_time_factor``, for people watching); and whether a
scenario's warnings refuse the run (strict). The orchestrator
hands the node-side fields to every node process on its command line (``to_json``), never
through the environment.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from plan.listen import LIVE_DEFAULT, ROSBRIDGE_DEFAULT, ListenAddress, parse_listen

if TYPE_CHECKING:
    from plan.scenario import Scenario

SPAWN_MODES = ("fork", "exec")
PACKINGS = ("node", "robot", "kind")
PROFILE_MODES = ("wall", "cpu")
TRANSPORTS = ("ros2", "zenoh")  # the scenario's transport: (plan.model), --transport
"""The choices of the run options, spelled once: the CLI's ``choices=`` and the checks of
``RunOptions`` read them (tests/test_architecture.py holds the type hints to them)."""


@dataclass(frozen=True)
class RunOptions:
    """One run's options (CLI flags, API keywords and the pytest plugin all build this)."""

    out: Path = Path("runs")
    in_process: bool = False
    paused: bool = False
    export_usd: bool = False
    pipeline: bool = True  # False: every node finishes tick k before /clock says k + 1
    spawn: Literal["fork", "exec"] = "fork"  # exec: fresh interpreters for cosim nodes
    zenoh_shm: bool = True  # zenoh's shared-memory transport for large messages
    zenoh_express: bool = False  # zenoh: write every message at once instead of batching
    camera_warm_up: bool = True  # build the camera's GL renderer in a thread at set-up
    profile: Literal["wall", "cpu"] | None = None  # a cProfile of each node in its run dir
    pack: Literal["node", "robot", "kind"] | None = None  # None: the scenario's process: keys
    spread: int | None = None  # with pack kind: each kind's nodes over at most N processes
    shuffle_start: int | None = None  # tests: start node processes in a seeded order
    strict: bool = False  # refuse a scenario with warnings (ScenarioError: exit 2)
    live: str | None = None  # ADDR:PORT of a Foxglove WebSocket server watching the run
    rosbridge: str | None = None  # ADDR:PORT of a rosbridge v2 server (watch and drive)
    twin: str | None = None  # ws://HOST:PORT of a real robot's rosbridge (a twin: scenario)
    real_time_factor: float | None = None  # pace: tick k starts no earlier than the first
    # tick's wall time + its sim time / R (orchestrator.lockstep.pace); None: unpaced
    picture: bool = True  # report.png after the run: about a CPU second, most of a short
    # run's cost (matplotlib's import and draw); a suite of many runs may go without

    def __post_init__(self) -> None:
        if self.spawn not in SPAWN_MODES:
            raise ValueError(f"spawn must be one of {', '.join(SPAWN_MODES)}, not {self.spawn!r}")
        if self.pack is not None and self.pack not in PACKINGS:
            raise ValueError(f"pack must be one of {', '.join(PACKINGS)} or None, "
                             f"not {self.pack!r}")
        if self.spread is not None and (self.pack != "kind" or self.spread < 1):
            raise ValueError(f"spread {self.spread!r} spreads the nodes of a kind over that "
                             "many processes: a whole number >= 1, with pack kind")
        if self.profile is not None and self.profile not in PROFILE_MODES:
            raise ValueError(f"profile must be one of {', '.join(PROFILE_MODES)} or None, "
                             f"not {self.profile!r}")
        if self.real_time_factor is not None:
            object.__setattr__(self, "real_time_factor",
                               check_real_time_factor(self.real_time_factor))
        object.__setattr__(self, "out", Path(self.out))
        for name, default in (("live", LIVE_DEFAULT), ("rosbridge", ROSBRIDGE_DEFAULT)):
            text = getattr(self, name)
            if text is not None:
                try:
                    object.__setattr__(self, name, str(parse_listen(str(text), default)))
                except ValueError as exc:
                    raise ValueError(f"{name}: {exc}") from None

        if self.twin is not None:
            from plan.twin import parse_twin_url

            object.__setattr__(self, "twin", parse_twin_url(self.twin).url)

    @property
    def live_address(self) -> ListenAddress | None:
        """Where the Foxglove live view listens (None: no live view)."""
        return parse_listen(self.live, LIVE_DEFAULT) if self.live else None

    @property
    def rosbridge_address(self) -> ListenAddress | None:
        """Where the rosbridge server listens (None: no rosbridge)."""
        return parse_listen(self.rosbridge, ROSBRIDGE_DEFAULT) if self.rosbridge else None

    def with_(self, **changes) -> RunOptions:
        """A copy with some fields changed."""
        return replace(self, **changes)

    def node_json(self) -> str:
        """The fields a node process needs, as JSON for its command line."""
        return json.dumps({f: getattr(self, f) for f in NODE_FIELDS})

    @classmethod
    def from_node_json(cls, text: str | None) -> RunOptions:
        """Options rebuilt in a node process from ``node_json`` (defaults when None)."""
        if not text:
            return cls()
        values = json.loads(text)
        unknown = set(values) - set(NODE_FIELDS)
        if unknown:
            raise ValueError(f"unknown run option(s) {', '.join(sorted(unknown))}")
        return cls(**values)

    def as_dict(self) -> dict:
        """JSON-ready fields, for the manifest."""
        out = asdict(self)
        out["out"] = str(self.out)
        return out


def check_real_time_factor(value: object, name: str = "real_time_factor") -> float:
    """``value`` as a pace (a finite number above 0: 1.0 is real time, 2.0 twice as fast);
    a ValueError naming ``name`` otherwise."""
    try:
        factor = float(value) if not isinstance(value, bool) else math.nan
    except (TypeError, ValueError):
        factor = math.nan
    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"{name} {value!r}: expected a number above 0 (1.0: real time, "
                         "2.0: twice as fast as the wall clock); leave it out for a run as "
                         "fast as it goes")
    return factor


NODE_FIELDS = ("zenoh_shm", "zenoh_express", "camera_warm_up", "profile", "pack", "spread")
"""The options a node process acts on."""

assert set(NODE_FIELDS) <= {f.name for f in fields(RunOptions)}


@dataclass(frozen=True)
class TransportSettings:
    """Which transport a participant opens and, for zenoh, where sessions meet.

    Built from the scenario (``transport:`` and its ``zenoh:`` section) and the run options,
    by the orchestrator and by every node process alike, so both sides agree without any
    setting passing through the environment.
    """

    kind: str = "ros2"
    zenoh_listen: tuple[str, ...] = ()
    zenoh_connect: tuple[str, ...] = ()
    zenoh_shm: bool = True
    zenoh_express: bool = False
    mirror_to_dds: tuple[str, ...] = field(default=())

    @classmethod
    def of(cls, scenario: Scenario, options: RunOptions | None = None) -> TransportSettings:
        """The settings of a checked scenario run with ``options``."""
        model = scenario.model
        return cls(kind=model.transport, zenoh_listen=tuple(model.zenoh.listen),
                   zenoh_connect=tuple(model.zenoh.connect),
                   zenoh_shm=(options or RunOptions()).zenoh_shm,
                   zenoh_express=(options or RunOptions()).zenoh_express,
                   mirror_to_dds=tuple(model.zenoh.mirror_to_dds))
