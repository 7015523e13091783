"""Per-topic digests, the rendered topics, and what a digest depends on (for the manifest).

The run digest covers every message of a run. Beside it the manifest keeps one digest per
topic (sha256 over each message's tick, length and serialised bytes, in tick order, from the
bag) and the digest of the run *without its rendered topics*: camera images are pixels from a
GL renderer (GPU EGL, Mesa's software llvmpipe, and their versions), which differ between
machines where nothing else does. A comparison that is asked to leave the rendered topics
out (``--ignore-rendered``, ``pytest --cosim-ignore-rendered``) compares that digest.

``digest_versions`` lists the software whose version can change a digest's bits: MuJoCo
(the physics, the ray casts), numpy (the arithmetic of the nodes), Python, and the renderer
when a run has rendered topics. Golden files and ``--against`` name the ones that differ.
"""

from __future__ import annotations

import hashlib
import platform
import struct
from importlib import metadata
from pathlib import Path

from orchestrator.outputs.renderer import RendererProbe
from plan.timeutil import Ns, tick_at_ns

CLOCK_TOPIC = "/clock"


def topic_digests(bag: Path, tick_ns: Ns) -> dict[str, str]:
    """{topic: sha256 hex} over every message but /clock of a rosbag2 directory, each topic's
    messages folded as (tick, length, bytes) in the order they were logged."""
    from orchestrator.outputs.bag import BagReader

    hashes: dict[str, hashlib._Hash] = {}
    with BagReader(Path(bag)) as reader:
        for topic, stamp, raw in reader.raw(exclude=[CLOCK_TOPIC]):
            h = hashes.setdefault(topic, hashlib.sha256())
            h.update(struct.pack("<qQ", tick_at_ns(stamp, tick_ns), len(raw)))
            h.update(raw)
    return {topic: h.hexdigest() for topic, h in sorted(hashes.items())}


def digest_of_topics(digests: dict[str, str], leave_out: set[str] | frozenset[str] = frozenset()
                     ) -> str:
    """One sha256 hex over the per-topic digests of every topic not in ``leave_out``."""
    h = hashlib.sha256()
    for topic, digest in sorted(digests.items()):
        if topic not in leave_out:
            h.update(topic.encode() + b"\0" + bytes.fromhex(digest))
    return h.hexdigest()


def rendered_topics(scenario) -> list[str]:
    """The graph topics a node of the scenario renders with GL (its class's
    ``rendered_outputs``), sorted."""
    from nodes.registry import load_class
    from plan.roles import NodeRole

    out: set[str] = set()
    for plan in scenario.nodes.values():
        if plan.role is NodeRole.ORCHESTRATOR:
            continue
        rendered = getattr(load_class(plan.class_ref), "rendered_outputs", None)
        if rendered is not None:
            out.update(plan.output_names[own] for own in rendered(plan.params)
                       if own in plan.output_names)
    return sorted(out)


def digest_versions(renderer: RendererProbe | None = None) -> dict[str, str]:
    """The versions a digest depends on: python, numpy, mujoco, the CPU architecture, and the
    renderer (when the run has rendered topics, whose probe is given)."""
    out = {"python": platform.python_version(), "machine": platform.machine()}
    for name in ("numpy", "mujoco"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    if renderer is not None:
        out["renderer"] = renderer.result()
    return out


def version_changes(before: dict[str, str] | None, after: dict[str, str] | None) -> list[str]:
    """['mujoco 3.3.0 -> 4.0.0', ...] for every version both name and that differs."""
    before, after = before or {}, after or {}
    return [f"{key} {before[key]} -> {after[key]}" for key in sorted(set(before) & set(after))
            if before[key] != after[key]]
