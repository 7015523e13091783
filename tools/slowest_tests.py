"""The slowest tests of a run, from the JUnit XML that `make test` keeps (build/test-times*.xml).

`python tools/slowest_tests.py [--top 30] [TIMES.xml ...] [--before OLD.xml]` prints a Markdown
table of the slowest tests (setup, call and teardown together, as JUnit counts them), with each
one's time in an earlier run beside it when --before names that run's file: the table
bench/README.md keeps. The total of every test's time is printed under it.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

BUILD = Path(__file__).resolve().parent.parent / "build"
DEFAULT = (BUILD / "test-times.xml", BUILD / "test-times-alone.xml")  # make test's two phases


def test_times(*paths: Path) -> dict[str, float]:
    """Seconds per test ('file::name[param]') in JUnit XML files."""
    times: dict[str, float] = {}
    for case in (c for path in paths for c in ET.parse(path).iter("testcase")):
        module = case.get("classname", "").replace(".", "/")
        name = f"{module}.py::{case.get('name')}"
        times[name] = times.get(name, 0.0) + float(case.get("time") or 0.0)
    return times


def table(now: dict[str, float], before: dict[str, float] | None, top: int) -> str:
    """The Markdown table of the ``top`` slowest tests of ``now`` (``before`` beside them)."""
    slowest = sorted(now.items(), key=lambda item: -item[1])[:top]
    head = "| test | s |" if before is None else "| test | before s | after s |"
    rule = "| --- | ---: |" if before is None else "| --- | ---: | ---: |"
    rows = [head, rule]
    for name, seconds in slowest:
        if before is None:
            rows.append(f"| `{name}` | {seconds:.1f} |")
        else:
            old = before.get(name)
            rows.append(f"| `{name}` | {'-' if old is None else f'{old:.1f}'} | {seconds:.1f} |")
    total = f"all {len(now)} tests: {sum(now.values()):.0f} s of test time"
    if before is not None:
        total += f" (before: {len(before)} tests, {sum(before.values()):.0f} s)"
    return "\n".join(rows) + "\n\n" + total


def main(argv: list[str] | None = None) -> int:
    """Print the table; 1 when a file is missing."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("times", nargs="*", type=Path,
                        help="JUnit XML files (default: make test's, those that exist)")
    parser.add_argument("--before", type=Path, help="an earlier run's JUnit XML")
    parser.add_argument("--top", type=int, default=30)
    args = parser.parse_args(argv)
    times = args.times or [p for p in DEFAULT if p.is_file()]
    for path in (*times, args.before):
        if path is not None and not path.is_file():
            print(f"slowest_tests: no file {path} (make test writes {DEFAULT[0]})",
                  file=sys.stderr)
            return 1
    if not times:
        print(f"slowest_tests: no {DEFAULT[0]}: run make test first", file=sys.stderr)
        return 1
    before = test_times(args.before) if args.before else None
    print(table(test_times(*times), before, args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main())
