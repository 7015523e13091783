"""The summary's Twin section: the link to the robot and what the network did, per topic
(from the manifest's ``live.twin``, written by ``orchestrator.proxies.twin``)."""

from __future__ import annotations

from typing import Any


def twin_rows(twin: dict[str, Any]) -> list[tuple[str, str]]:
    """(label, text) rows: the robot, one per robot topic, what went back."""
    rows = [("robot", f"{twin['url']}: connected {twin['connects']} time(s), "
                      f"{twin['reconnects']} reconnect(s), {twin['connected_s']:.1f} s "
                      f"connected")]
    for robot, t in twin.get("topics", {}).items():
        if t["never_arrived"]:
            rows.append((robot, f"-> {t['as']}: nothing arrived"))
            continue
        text = (f"-> {t['as']}: {t['arrived']} arrived, {t['entered']} entered, "
                f"{t['lost']} lost")
        if t["delay"]:
            d = t["delay"]
            base = "" if t["clock"] == "shared" else " above the fastest (clocks not shared)"
            text += f"; delay p50 {d['p50_ms']:.1f} ms, p99 {d['p99_ms']:.1f} ms{base}"
        if t.get("mirror_delay"):
            m = t["mirror_delay"]
            text += f"; mirror delay p50 {m['p50_ms']:.1f} ms, p99 {m['p99_ms']:.1f} ms"
        if t["stale_periods"]:
            text += (f"; stale {t['stale_periods']} time(s), {t['stale_s']:.1f} s"
                     + (", stale at the end" if t["stale_at_end"] else ""))
        rows.append((robot, text))
    sent = twin.get("sent") or {}
    if sent:
        rows.append(("sent back", ", ".join(f"{topic} {n}" for topic, n in sent.items())))
    if twin.get("robot_errors"):
        rows.append(("robot said", "; ".join(twin["robot_errors"])[:300]))
    if twin.get("ticks_behind_wall_clock"):
        rows.append(("behind", f"{twin['ticks_behind_wall_clock']} tick(s) decided more than "
                               "a tick late"))
    return rows


def twin_line(twin: dict[str, Any]) -> str:
    """The network in a few lines, for the report picture."""
    lines = [f"twin of {twin['url']}: {twin['reconnects']} reconnect(s)"]
    for robot, t in twin.get("topics", {}).items():
        if t["never_arrived"]:
            lines.append(f"{robot}: nothing arrived")
            continue
        d, m = t.get("delay") or {}, t.get("mirror_delay") or {}
        lines.append(f"{robot}: {t['arrived']} arrived, {t['lost']} lost, delay p50/p99 "
                     f"{d.get('p50_ms', 0):.1f}/{d.get('p99_ms', 0):.1f} ms, mirror "
                     f"{m.get('p50_ms', 0):.1f}/{m.get('p99_ms', 0):.1f} ms"
                     + (f", stale {t['stale_periods']}x {t['stale_s']:.1f} s"
                        if t["stale_periods"] else ""))
    return "\n".join(lines)
