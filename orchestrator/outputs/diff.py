"""Where two runs part: the first (tick, topic) whose recorded message differs.

The run digest says *whether* two runs differ; this module says *where*, down to the first
field of the first message that differs, with both values (``runtime.message_diff``).
Every message of a run's bag is hashed (its serialised bytes are canonical: equal messages
give equal bytes) and the two runs are walked side by side in (tick, topic) order. ``/clock``
is left out: it is not part of the digest and depends only on how many ticks ran.

A run can also be kept as a compact *fingerprint* (per topic: its ticks as arithmetic runs and
a short hash prefix per message, base64) so a golden file can name the first difference
without keeping the golden run's bag.
"""

from __future__ import annotations

import base64
import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from plan.ros_types import message_class
from plan.run_paths import RunPaths
from plan.timeutil import Ns, parse_tick_ns, tick_at_ns, tick_time_ns
from runtime.message_diff import field_difference

CLOCK_TOPIC = "/clock"
FINGERPRINT_HASH_BYTES = 3
"""Bytes of sha256 kept per message in a fingerprint: 4 base64 characters, a chance of
1 in 16.7 million that one changed message goes unnoticed (the next one then names it)."""

Entry = tuple[int, str, bytes]
"""(tick, topic, sha256 of the message's serialised bytes, or a prefix of it)."""


@dataclass(frozen=True)
class Difference:
    """The first place two runs differ: a tick, a topic and what is different there."""

    tick: int
    topic: str
    kind: str  # differs | missing (only in the reference) | extra (only in this run)
    tick_ns: Ns | None = None
    occurrence: int = 0  # which message of this topic at this tick (0: the first)
    field: str | None = None  # where two messages differ: 'angular.x: 6.91e-310 vs 6.95e-310'

    def describe(self) -> str:
        """'topic /odom at tick 37 (t = 0.740 s): pose.pose.position.x: 1.25 vs 1.5' (the
        reference run's value first), or '...: the message differs' when no field is named."""
        when = (f" (t = {tick_time_ns(self.tick, self.tick_ns) / 1e9:.3f} s)" if self.tick_ns
                else "")
        what = {"differs": self.field or "the message differs",
                "missing": "the reference run has a message here, this run has none",
                "extra": "this run has a message here, the reference run has none"}[self.kind]
        return f"topic {self.topic} at tick {self.tick}{when}: {what}"


def bag_entries(bag: Path, tick_ns: Ns) -> list[Entry]:
    """Every message of a rosbag2 directory but /clock as (tick, topic, sha256), sorted."""
    from orchestrator.outputs.bag import BagReader

    with BagReader(Path(bag)) as reader:
        entries = [(tick_at_ns(stamp, tick_ns), topic, hashlib.sha256(raw).digest())
                   for topic, stamp, raw in reader.raw(exclude=[CLOCK_TOPIC])]
    entries.sort(key=lambda e: (e[0], e[1]))
    return entries


def run_dir_entries(run_dir: Path) -> tuple[list[Entry], Ns]:
    """A run directory's messages (see ``bag_entries``) and its tick in ns, from the manifest."""
    manifest = json.loads(RunPaths(Path(run_dir)).manifest.read_text())
    tick_ns = parse_tick_ns(manifest["tick_ns"])
    return bag_entries(run_bag(run_dir), tick_ns), tick_ns


def run_bag(run_dir: Path) -> Path:
    """A run directory's bag, as its manifest names it."""
    manifest = json.loads(RunPaths(Path(run_dir)).manifest.read_text())
    return Path(run_dir) / (manifest.get("outputs", {}).get("bag") or "bag")


def first_difference(reference: Iterable[Entry], actual: Iterable[Entry],
                     tick_ns: Ns | None = None) -> Difference | None:
    """The first (tick, topic) where two sorted entry lists differ; None when they agree.

    Hashes of different lengths (a fingerprint's prefix against a full hash) are compared on
    the shorter length.
    """
    ref, act = _keyed(reference), _keyed(actual)
    for key in sorted(set(ref) | set(act)):
        tick, topic, occurrence = key
        if key not in act:
            return Difference(tick, topic, "missing", tick_ns, occurrence)
        if key not in ref:
            return Difference(tick, topic, "extra", tick_ns, occurrence)
        a, b = ref[key], act[key]
        n = min(len(a), len(b))
        if a[:n] != b[:n]:
            return Difference(tick, topic, "differs", tick_ns, occurrence)
    return None


def with_field(diff: Difference, reference_bag: Path, bag: Path) -> Difference:
    """``diff`` naming the first field that differs (``field``), both messages decoded from
    the two bags; unchanged when it is not a differing message or the messages cannot be
    decoded."""
    if diff.kind != "differs" or not diff.tick_ns:
        return diff
    first = message_at(reference_bag, diff.topic, diff.tick, diff.tick_ns, diff.occurrence)
    second = message_at(bag, diff.topic, diff.tick, diff.tick_ns, diff.occurrence)
    if first is None or second is None:
        return diff
    found = field_difference(first, second)
    if found is None:
        return replace(diff, field="the bytes differ where no field is (padding)")
    return replace(diff, field=found.describe())


def message_at(bag: Path, topic: str, tick: int, tick_ns: Ns, occurrence: int = 0) -> Any:
    """The ``occurrence``-th message of ``topic`` at ``tick`` in a bag, decoded (as the
    rclpy class its type names, else as a rosbags object); None when there is none."""
    from orchestrator.outputs.bag import BagReader
    from runtime.cdr.decode import decode

    with BagReader(Path(bag)) as reader:
        found = [raw for _, _, raw in reader.raw([topic], start=tick_time_ns(tick, tick_ns),
                                                 stop=tick_time_ns(tick + 1, tick_ns))]
        if len(found) <= occurrence:
            return None
        raw = found[occurrence]
        try:
            return decode(raw, message_class(reader.msgtype(topic)))
        except ValueError:  # a type not installed here: the bag's own definition
            return reader.deserialize(raw, topic)


def _keyed(entries: Iterable[Entry]) -> dict[tuple[int, str, int], bytes]:
    """Entries keyed by (tick, topic, occurrence within that tick and topic)."""
    out: dict[tuple[int, str, int], bytes] = {}
    for tick, topic, digest in entries:
        n = 0
        while (tick, topic, n) in out:
            n += 1
        out[(tick, topic, n)] = digest
    return out


def fingerprint(entries: Iterable[Entry]) -> dict[str, dict]:
    """A compact per-topic form of entries: {topic: {'ticks': 'start:step:count ...' (runs
    of evenly spaced ticks), 'hashes': base64 of FINGERPRINT_HASH_BYTES per message}}."""
    by_topic: dict[str, tuple[list[int], bytearray]] = {}
    for tick, topic, digest in entries:
        ticks, hashes = by_topic.setdefault(topic, ([], bytearray()))
        ticks.append(tick)
        hashes += digest[:FINGERPRINT_HASH_BYTES]
    return {topic: {"ticks": _runs(ticks), "hashes": base64.b64encode(bytes(hashes)).decode()}
            for topic, (ticks, hashes) in sorted(by_topic.items())}


def fingerprint_entries(print_: dict[str, dict]) -> list[Entry]:
    """The entries a fingerprint stands for (hashes shortened to the fingerprint's prefix)."""
    entries: list[Entry] = []
    for topic, item in print_.items():
        hashes = base64.b64decode(item["hashes"])
        ticks = _expand(item["ticks"])
        size = len(hashes) // max(len(ticks), 1)
        entries += [(tick, topic, hashes[i * size:(i + 1) * size]) for i, tick in enumerate(ticks)]
    entries.sort(key=lambda e: (e[0], e[1]))
    return entries


def _runs(ticks: list[int]) -> str:
    """[0, 2, 4, 6, 7] -> '0:2:4 7:1:1': arithmetic runs start:step:count."""
    runs: list[list[int]] = []
    for tick in ticks:
        if runs and runs[-1][2] == 1 and tick > runs[-1][0]:
            runs[-1][1], runs[-1][2] = tick - runs[-1][0], 2
        elif runs and runs[-1][0] + runs[-1][1] * runs[-1][2] == tick:
            runs[-1][2] += 1
        else:
            runs.append([tick, 1, 1])
    return " ".join(f"{start}:{step}:{count}" for start, step, count in runs)


def _expand(runs: str) -> list[int]:
    """The inverse of ``_runs``: '0:2:3 7:1:1' -> [0, 2, 4, 7]."""
    triples = [tuple(map(int, run.split(":"))) for run in runs.split()]
    return [start + step * i for start, step, count in triples for i in range(count)]


DIGEST_KEYS = {False: "digest", True: "digest_without_rendered"}
"""The manifest key compared: the run digest, or (ignoring rendered topics) the digest of
every topic but the rendered ones."""


def read_manifest(run_dir: Path) -> dict:
    """A run directory's manifest.json as a dict."""
    return json.loads(RunPaths(Path(run_dir)).manifest.read_text())


def expected_digest(given: str | None, against: Path | None,
                    ignore_rendered: bool = False) -> str | None:
    """The digest a run must have (--expect-digest, else --against DIR's; with
    ``ignore_rendered`` DIR's digest without its rendered topics); ValueError when the hex is
    malformed or DIR is not a recorded run with that digest and a bag."""
    if against is not None:
        manifest = RunPaths(Path(against)).manifest
        if not manifest.is_file():
            raise ValueError(f"--against {against}: not a run directory (no manifest.json)")
        recorded = json.loads(manifest.read_text())
        if not (Path(against) / (recorded.get("outputs", {}).get("bag") or "bag")).is_dir():
            raise ValueError(f"--against {against}: the run has no bag to compare with")
        key = DIGEST_KEYS[ignore_rendered]
        if not given and key not in recorded:
            raise ValueError(f"--against {against}: its manifest has no {key} (recorded before "
                             "cosim kept per-topic digests); record it again, or give "
                             "--expect-digest HEX")
        given = given or recorded.get(key)
        if not given:
            raise ValueError(f"--against {against}: the run has no digest (it did not finish); "
                             "give --expect-digest HEX")
    if given is None:
        return None
    text = given.strip().lower()
    if len(text) != 64 or any(c not in "0123456789abcdef" for c in text):
        raise ValueError(f"--expect-digest {given!r}: expected 64 hex digits (a sha256 digest "
                         "as printed by cosim-orchestrate)")
    return text


def left_out_text(rendered: list[str]) -> str:
    """'without the rendered topics /a, /b (left out of the comparison)'."""
    names = ", ".join(rendered) if rendered else "none in this run"
    return f"without the rendered topics ({names}: left out of the comparison)"


def digest_mismatch(expected: str, run_dir: Path, against: Path | None,
                    ignore_rendered: bool = False) -> str | None:
    """None when the run in ``run_dir`` has the expected digest (with ``ignore_rendered``:
    its digest without the rendered topics), else a message naming the first topic and tick
    that differ from the run directory ``against`` (when given), the rendered topics left
    out, and the versions a digest depends on that differ between the two runs."""
    manifest = read_manifest(run_dir)
    got = manifest.get(DIGEST_KEYS[ignore_rendered])
    if got == expected:
        return None
    rendered = list(manifest.get("rendered_topics") or [])
    which = f"the digest {left_out_text(rendered)}" if ignore_rendered else "digest"
    text = f"{which} mismatch: expected {expected}, got {got}."
    if against is None:
        return text + _rendered_hint(manifest, None, ignore_rendered) + (
            " Give --against DIR (a recorded run with the expected digest) to name the first "
            "topic and tick that differ.")
    reference, tick_ns = run_dir_entries(Path(against))
    actual, _ = run_dir_entries(Path(run_dir))
    if ignore_rendered:
        left_out = set(rendered) | set(read_manifest(against).get("rendered_topics") or [])
        reference = [e for e in reference if e[1] not in left_out]
        actual = [e for e in actual if e[1] not in left_out]
    diff = first_difference(reference, actual, tick_ns)
    if diff is not None:
        diff = with_field(diff, run_bag(against), run_bag(run_dir))
    if diff is None:
        text += (f" Every recorded message equals {against}'s; the runs differ in what "
                 "the digest covers beyond the messages (nodes, schedule).")
    else:
        text += f" First difference from {against}: {diff.describe()}."
    reference_manifest = read_manifest(against)
    text += _rendered_hint(manifest, reference_manifest, ignore_rendered)
    return text + versions_text(reference_manifest.get("digest_versions"),
                                manifest.get("digest_versions"))


def _rendered_hint(manifest: dict, reference: dict | None, ignore_rendered: bool) -> str:
    """When only rendered topics differ (or may): say so and how to leave them out."""
    rendered = list(manifest.get("rendered_topics") or [])
    if ignore_rendered or not rendered:
        return ""
    renderer = (manifest.get("digest_versions") or {}).get("renderer", "unknown")
    without = reference.get("digest_without_rendered") if reference is not None else None
    if without is not None and without == manifest.get("digest_without_rendered"):
        return (f" Only the rendered topics ({', '.join(rendered)}) differ; their pixels "
                f"depend on the renderer (this run: {renderer}). --ignore-rendered compares "
                "without them.")
    if without is not None:  # the rest differs too: not (only) the renderer's doing
        return (" The topics that are not rendered differ too: more than the renderer "
                "changed (another seed, scenario, input or version).")
    # only a digest to compare with: which part differs is unknown, so blame nothing
    return (f" The digest also covers rendered topics ({', '.join(rendered)}), whose pixels "
            f"depend on the renderer (this run: {renderer}): if a run on another machine is "
            f"the reference, compare its digest_without_rendered with --ignore-rendered "
            f"(this run's: {manifest.get('digest_without_rendered')}).")


def versions_text(before: dict | None, after: dict | None) -> str:
    """' The versions a digest depends on differ: mujoco 3.3.0 -> 4.0.0.' or ''."""
    from orchestrator.outputs.topic_digests import version_changes

    changes = version_changes(before, after)
    if not changes:
        return ""
    return (" The versions a digest depends on differ (reference -> this run): "
            + "; ".join(changes) + ".")
