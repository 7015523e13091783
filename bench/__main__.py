"""`python -m bench` (make bench): every benchmark, one after the other, in one run.

Each section runs on its own: one that fails prints why and the next one runs, so the
command always reaches the end (and exits non-zero if a section failed)."""

import sys
import traceback

from bench import (
    crowd_worlds,
    foreign_nav,
    live,
    lockstep,
    messages,
    nav,
    nav_worlds,
    peers,
    profile,
    ros2_control,
    sensors,
    sweep,
    twin,
    urdf,
    zenoh_chain,
)

SECTIONS = [
    ("lockstep: ticks/s, trivial nodes at 1 kHz",
     lambda: lockstep.main(["--chain-repeats", "3", "--parallel", "1", "2", "3", "4", "5", "6",
                            "7", "8"])),
    ("lockstep over zenoh: the same chain",
     lambda: lockstep.main(["--transport", "zenoh", "--chain-repeats", "3", "--parallel"])),
    ("zenoh against ros2: chain ticks/s and CPU per tick, nav, payloads",
     lambda: zenoh_chain.main(["--repeats", "3"])),
    ("the chain beside HELICS 3 and mosaik 3 (when installed)",
     lambda: peers.main(["--repeats", "2"])),
    ("nav: multi-process over in-process", lambda: nav.main(["--repeats", "3"])),
    ("nav over zenoh: multi-process over in-process",
     lambda: nav.main(["--transport", "zenoh", "--repeats", "3"])),
    ("nav: the controller as a foreign rclpy program over built-in, per gate",
     lambda: foreign_nav.main(["--repeats", "3"])),
    ("nav: the same, timer-driven (callbacks store, a 10 Hz timer publishes)",
     lambda: foreign_nav.main(["--repeats", "3", "--timer"])),
    ("nav: with the Foxglove live view and one client over without",
     lambda: live.main(["--repeats", "3"])),
    ("digital twin: mirror delay on loopback at 50 Hz and faster robots",
     lambda: twin.main([])),
    ("nav: where each process spends its time (py-spy)", lambda: profile.main([])),
    ("your own robot: nav_urdf's URDF robot against the MJCF robot, start-up and loop",
     lambda: urdf.main(["--repeats", "3"])),
    ("ros2_control: the arm through the controller manager over /joint_commands alone",
     lambda: ros2_control.main(["--repeats", "3"])),
    ("message cost", messages.main),
    ("sensor cost", sensors.main),
    ("navigation over 50 generated worlds (in-process, 2 at a time)",
     lambda: nav_worlds.main(["--count", "50"])),
    ("crowds: 30 generated door swaps, plazas and corridors of 8-32 robots (in-process, 2 at "
     "a time)", lambda: crowd_worlds.main(["--count", "30"])),
    ("sweeps: 100 nav seeds in-process on every core, and on Ray", lambda: sweep.main([])),
]


def main() -> int:
    """Run every section in order; a failed one is reported and the rest still run."""
    failed = []
    for title, run in SECTIONS:
        print(f"\n== {title} ==", flush=True)
        try:
            run()
        except (Exception, SystemExit) as exc:  # a section's failure is its own
            failed.append(title)
            print(f"section failed: {type(exc).__name__}: {exc}")
            traceback.print_exc(limit=3)
    print(f"\n{len(SECTIONS) - len(failed)} of {len(SECTIONS)} sections ran to the end" +
          (f"; failed: {'; '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
