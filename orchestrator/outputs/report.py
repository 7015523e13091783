"""What the terminal shows at the end of a run.

A summary (outcome, metrics, per-node cost, digest, where the outputs are) on stdout: rich
tables on a terminal, plain aligned text otherwise so CI logs stay clean. The error, if
any, goes to stderr once. The last line of stdout is always the one-line verdict that
scripts and tests parse; ``--quiet`` prints only that line.

The numbers come from the run's manifest.json when it was written (the same numbers the
manifest keeps), else from the outcome alone.
"""

from __future__ import annotations

import json
import sys
from typing import Any

from plan.run_paths import RunPaths

STATUS_STYLE = {"success": "bold green", "goal_not_met": "bold yellow", "failed": "bold red",
                "interrupted": "bold magenta"}
METRICS = (("time_to_goal", "time to goal", "{:.2f} s"),
           ("path_length", "path length", "{:.2f} m"),
           ("min_clearance", "min clearance", "{:.3f} m"),
           ("recoveries", "recoveries", "{:g}"))
NOTES_SHOWN = 5  # the summary shows the first notes; the manifest and logs keep them all
NODE_COLUMNS = (("ticks", "ticks", "{:d}"), ("step_ms_mean", "mean step ms", "{:.3f}"),
                ("step_ms_worst", "worst step ms", "{:.3f}"), ("cpu_s", "CPU s", "{:.2f}"),
                ("peak_rss_mb", "peak MB", "{:.1f}"), ("ready_s", "ready s", "{:.2f}"))


def print_outcome(outcome, quiet: bool = False) -> None:
    """The error (if any) on stderr, the summary unless quiet, then the final line."""
    if outcome.error and outcome.status != "interrupted":
        print(f"cosim-orchestrate: {outcome.error}", file=sys.stderr)
    if not quiet:
        try:
            print_summary(outcome)
        except Exception as exc:  # noqa: BLE001 - the verdict line must still come out
            print(f"cosim-orchestrate: could not print the summary: {exc}", file=sys.stderr)
    print(final_line(outcome), flush=True)


def final_line(outcome) -> str:
    """'success: digest <hex> (12.34 s) -> runs/nav-...' (parsed by scripts and tests)."""
    digest = outcome.digest or "-"
    return f"{outcome.status}: digest {digest} ({outcome.wall_s:.2f} s) -> {outcome.run_dir}"


def print_summary(outcome) -> None:
    """The summary tables: rich on a terminal, plain text otherwise."""
    manifest = read_manifest(outcome)
    sections = [("Outcome", outcome_rows(outcome, manifest)),
                ("Outputs", output_rows(outcome))]
    twin = (manifest.get("live") or {}).get("twin")
    if twin:
        from orchestrator.outputs.twin_rows import twin_rows

        sections.insert(1, ("Twin", twin_rows(twin)))
    nodes = node_table(manifest)
    if sys.stdout.isatty():
        print_rich(outcome, sections, nodes)
    else:
        sys.stdout.write(plain_text(sections, nodes))
        sys.stdout.flush()


def read_manifest(outcome) -> dict[str, Any]:
    """The run's manifest.json, or {} when it is missing or unreadable."""
    try:
        return json.loads(RunPaths(outcome.run_dir).manifest.read_text())
    except (OSError, ValueError, TypeError):
        return {}


def outcome_rows(outcome, manifest: dict[str, Any]) -> list[tuple[str, str]]:
    """Status, metrics, timing and digest as (label, text) rows."""
    rows = [("status", outcome.status), ("success", "yes" if outcome.success else "no"),
            ("collisions", str(outcome.collisions))]
    metrics = manifest.get("outcome", {}).get("metrics") or flat_metrics(outcome)
    if manifest.get("swarm"):  # many robots: per-robot lines instead of one robot's
        from orchestrator.outputs.swarm import swarm_rows

        rows += swarm_rows(manifest["swarm"])
        metrics = {}
    if "goal_reached" in metrics:
        rows.append(("goal reached", "yes" if metrics["goal_reached"] >= 1 else "no"))
    rows += [(label, metric_text(key, metrics[key], fmt))
             for key, label, fmt in METRICS if key in metrics]
    rows += note_rows(manifest.get("notes")
                      or [n.as_dict() for n in getattr(outcome, "notes", [])])
    rows.append(("time", timing_text(outcome, manifest)))
    if cost_text(manifest):
        rows.append(("orchestrator", cost_text(manifest)))
    rows.append(("digest", outcome.digest or "-"))
    return rows


def note_rows(notes: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """What the nodes noted ('control at 0.00 s: no path ...'), the first few of them."""
    rows = [("note", f"{n['node']} at {n['time_s']:.2f} s: {n['text']}")
            for n in notes[:NOTES_SHOWN]]
    if len(notes) > NOTES_SHOWN:
        rows.append(("note", f"... {len(notes) - NOTES_SHOWN} more in manifest.json"))
    return rows


def metric_text(key: str, value: float, fmt: str) -> str:
    """A metric for people: a negative time to goal means it was not reached."""
    if key == "time_to_goal" and value < 0:
        return "not reached"
    return fmt.format(value)


def flat_metrics(outcome) -> dict[str, float]:
    """Every node's metrics in one dict."""
    result = outcome.result
    return {k: v for m in (result.metrics.values() if result else []) for k, v in m.items()}


def timing_text(outcome, manifest: dict[str, Any]) -> str:
    """'28.60 s simulated in 9.14 s wall (3.13x real time; start-up 1.93 s), 1431 ticks'."""
    text = f"{outcome.wall_s:.2f} s wall"
    sim = manifest.get("sim_time_s")
    if sim is not None:
        text = f"{sim:.2f} s simulated in {text}"
    extra = []
    if manifest.get("real_time_factor"):
        extra.append(f"{manifest['real_time_factor']:.2f}x real time")
    if outcome.start_s and outcome.start_s >= 0.005:
        extra.append(f"start-up {outcome.start_s:.2f} s")
    if extra:
        text += f" ({'; '.join(extra)})"
    ticks = manifest.get("ticks", outcome.result.ticks if outcome.result else None)
    return text + (f", {ticks} ticks" if ticks is not None else "")


def node_table(manifest: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the per-node cost table ('-' where a number is not known)."""
    entries = manifest.get("nodes") or {}
    columns = [c for c in NODE_COLUMNS if any(c[0] in e for e in entries.values())]
    header = ["node"] + [label for _, label, _ in columns]
    rows = []
    for name, entry in entries.items():
        cells = [name]
        for key, _, fmt in columns:
            value = entry.get(key)
            cells.append("-" if value is None else fmt.format(value))
        rows.append(cells)
    return header, rows


def cost_text(manifest: dict[str, Any]) -> str | None:
    """The orchestrator process's own CPU and peak memory (in-process: every node's)."""
    cost = manifest.get("orchestrator")
    if not cost:
        return None
    who = "every node, in-process" if manifest.get("transport") == "in-process" else "its own"
    return f"CPU {cost['cpu_s']:.2f} s, peak {cost['peak_rss_mb']:.0f} MB ({who})"


def output_rows(outcome) -> list[tuple[str, str]]:
    """Where the run's files are."""
    paths = RunPaths(outcome.run_dir)
    rows = [("run directory", str(paths.root)), ("manifest", str(paths.manifest))]
    rows.append(("bag (MCAP)", str(outcome.bag) if outcome.bag else "not written"))
    rows.append(("report.png", str(outcome.report) if outcome.report else "not drawn"))
    rows.append(("logs", str(paths.logs)))
    if getattr(outcome, "usd", None):  # --export-usd
        rows.append(("run.usda", str(outcome.usd)))
        rows += [("robot (USD)", str(p)) for p in sorted((paths.root / "robots").glob("*.usda"))]
    return rows


def plain_text(sections, nodes) -> str:
    """The summary as plain aligned text."""
    lines: list[str] = []
    width = max(len(label) for _, rows in sections for label, _ in rows)
    for title, rows in sections[:1]:
        lines += [f"{title}:"] + [f"  {label:<{width}}  {text}" for label, text in rows]
    header, rows = nodes
    if rows:
        widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
        lines.append("Nodes:")
        for row in [header, *rows]:
            cells = [row[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(row[1:], widths[1:],
                                                                           strict=True)]
            lines.append("  " + "  ".join(cells))
    for title, rows in sections[1:]:
        lines += [f"{title}:"] + [f"  {label:<{width}}  {text}" for label, text in rows]
    return "\n".join(lines) + "\n"


def print_rich(outcome, sections, nodes) -> None:
    """The summary as rich tables on the terminal."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    style = STATUS_STYLE.get(outcome.status, "bold")
    for title, rows in sections[:1]:
        console.print(key_value_table(Table, title, rows, {"status": style}))
    header, rows = nodes
    if rows:
        table = Table(title="Nodes", title_justify="left", header_style="bold")
        for i, label in enumerate(header):
            table.add_column(label, justify="left" if i == 0 else "right")
        for row in rows:
            table.add_row(*row)
        console.print(table)
    for title, rows in sections[1:]:
        console.print(key_value_table(Table, title, rows, {}))


def key_value_table(table_class, title: str, rows, styles: dict[str, str]):
    """A two-column rich table without a header."""
    table = table_class(title=title, title_justify="left", show_header=False)
    table.add_column(style="bold")
    table.add_column(overflow="fold")
    for label, text in rows:
        table.add_row(label, text, style=styles.get(label))
    return table
