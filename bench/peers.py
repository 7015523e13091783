"""cosim's 3-node chain beside the same chain in HELICS 3 and mosaik 3, when they are installed.

    python -m bench.peers [--steps 3000] [--repeats 2]

Each framework runs three trivial federates / simulators in a chain n0 -> n1 -> n2 (each adds
one to what it received), one process each where the framework has processes, stepping 1 ms
of simulated time per step; the figure is steps per wall second of the whole chain, measured
in this invocation, side by side, rounds interleaved. HELICS and mosaik are not dependencies
of cosim: `pip install helics mosaik` to include them; a framework that is missing is named
and skipped.
"""

from __future__ import annotations

import argparse
import importlib.util
import multiprocessing
import statistics
import tempfile
import time
from pathlib import Path

from bench.common import run_manifest, write_scenario
from bench.lockstep import chain

PERIOD_S = 0.001  # one step: the cosim chain's 1 kHz tick


def cosim_chain(steps: int, transport: str = "ros2") -> float:
    """Ticks/s of cosim's 3-node same-tick chain (full protocol, multi-process)."""
    seconds = max(1, round(steps * PERIOD_S))
    with tempfile.TemporaryDirectory() as tmp:
        path = write_scenario(chain(3, seconds), Path(tmp))
        return run_manifest(path, "--transport", transport)["ticks_per_s"]


def _helics_federate(index: int, steps: int, core_init: str) -> None:
    import helics as h

    info = h.helicsCreateFederateInfo()
    h.helicsFederateInfoSetCoreTypeFromString(info, "zmq")
    h.helicsFederateInfoSetCoreInitString(info, core_init)
    h.helicsFederateInfoSetTimeProperty(info, h.HELICS_PROPERTY_TIME_DELTA, PERIOD_S)
    fed = h.helicsCreateValueFederate(f"n{index}", info)
    pub = h.helicsFederateRegisterGlobalTypePublication(fed, f"n{index}", "double", "")
    sub = (h.helicsFederateRegisterSubscription(fed, f"n{index - 1}", "")
           if index else None)
    h.helicsFederateEnterExecutingMode(fed)
    for k in range(1, steps + 1):
        h.helicsFederateRequestTime(fed, k * PERIOD_S)
        value = h.helicsInputGetDouble(sub) if sub is not None else 0.0
        h.helicsPublicationPublishDouble(pub, value + 1.0)
    h.helicsFederateDisconnect(fed)
    h.helicsFederateFree(fed)


def helics_chain(steps: int) -> float:
    """Steps/s of a HELICS chain of three value federates, one process each, zmq core."""
    import helics as h

    broker = h.helicsCreateBroker("zmq", "", "-f 3 --loglevel=warning")
    spawn = multiprocessing.get_context("spawn")  # a forked copy of the broker's zmq breaks
    procs = [spawn.Process(target=_helics_federate,
                                     args=(i, steps, "--federates=1 --loglevel=warning"))
             for i in range(3)]
    start = time.perf_counter()
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=600)
    elapsed = time.perf_counter() - start
    h.helicsBrokerWaitForDisconnect(broker, 10_000)
    h.helicsBrokerFree(broker)
    if any(p.exitcode != 0 for p in procs):
        raise RuntimeError(f"a HELICS federate failed: exit codes {[p.exitcode for p in procs]}")
    return steps / elapsed


class _Counter:
    """A mosaik 3 simulator: one entity that adds one to its input each step."""

    def __new__(cls):  # built lazily so that mosaik_api_v3 is imported only when installed
        import mosaik_api_v3

        class Counter(mosaik_api_v3.Simulator):
            def __init__(self):
                super().__init__({"type": "time-based", "models": {
                    "C": {"public": True, "params": [], "attrs": ["x", "y"]}}})
                self.value = 0.0

            def init(self, sid, time_resolution=1.0, **sim_params):
                return self.meta

            def create(self, num, model, **params):
                return [{"eid": "c", "type": model}]

            def step(self, time, inputs, max_advance):
                received = [v for attrs in inputs.values() for vals in attrs.values()
                            for v in vals.values()]
                self.value = (received[0] if received else 0.0) + 1.0
                return time + 1

            def get_data(self, outputs):
                return {"c": {"y": self.value}}

        return Counter()


def mosaik_chain(steps: int) -> float:
    """Steps/s of a mosaik 3 chain of three counters (Python simulators: one process)."""
    import mosaik

    config = {f"n{i}": {"python": "bench.peers:_Counter"} for i in range(3)}
    world = mosaik.World(config, debug=False)
    counters = [world.start(f"n{i}").C.create(1)[0] for i in range(3)]
    for a, b in zip(counters, counters[1:], strict=False):
        world.connect(a, b, ("y", "x"))
    start = time.perf_counter()
    world.run(until=steps, print_progress=False)
    return steps / (time.perf_counter() - start)


PEERS = {"HELICS 3": ("helics", helics_chain),
         "mosaik 3 (1 process)": ("mosaik", mosaik_chain)}


def main(argv: list[str] | None = None) -> None:
    """Print cosim's chain and every installed peer's, rounds interleaved, and the ratios."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--repeats", type=int, default=2)
    args = p.parse_args(argv)
    runners = {"cosim ros2": lambda n: cosim_chain(n, "ros2"),
               "cosim zenoh": lambda n: cosim_chain(n, "zenoh")}
    for label, (module, fn) in PEERS.items():
        if importlib.util.find_spec(module) is None:
            print(f"{label}: not installed (pip install {module}), skipped")
        else:
            runners[label] = fn
    rates: dict[str, list[float]] = {label: [] for label in runners}
    for _ in range(args.repeats):
        for label, fn in runners.items():
            try:
                rates[label].append(fn(args.steps))
            except Exception as exc:  # one framework failing leaves the others measured
                print(f"{label}: not measured: {exc}")
    base = statistics.median(rates["cosim ros2"]) if rates["cosim ros2"] else None
    for label, values in rates.items():
        if values:
            ratio = f"  cosim ros2 / this {base / statistics.median(values):.2f}" if base else ""
            print(f"{label:20s} steps/s: " + ", ".join(f"{v:,.0f}" for v in values) + ratio)


if __name__ == "__main__":
    main()
