"""What the terminal shows at the end of a run."""

from __future__ import annotations

import sys


def print_outcome(outcome, quiet: bool = False) -> None:
    """The error (if any) on stderr, then one final line: status, digest, run directory."""
    if outcome.error and outcome.status != "interrupted":
        print(f"cosim-orchestrate: {outcome.error}", file=sys.stderr)
    digest = outcome.digest or "-"
    print(f"{outcome.status}: digest {digest} ({outcome.wall_s:.2f} s) -> {outcome.run_dir}")
