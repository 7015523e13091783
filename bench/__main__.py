"""`python -m bench` (make bench): every benchmark, one after the other, in one run."""

from bench import foreign_nav, live, lockstep, messages, nav, nav_worlds, profile, sensors, sweep


def main() -> None:
    """Lockstep (with scaling 1..8), nav, where nav's time goes, messages, sensors, the
    controller over 50 generated worlds, sweeps."""
    print("== lockstep: ticks/s, trivial nodes at 1 kHz ==")
    lockstep.main(["--chain-repeats", "3", "--parallel", "1", "2", "3", "4", "5", "6", "7", "8"])
    print("\n== lockstep over zenoh: the same chain ==")
    lockstep.main(["--transport", "zenoh", "--chain-repeats", "3", "--parallel"])
    print("\n== nav: multi-process over in-process ==")
    nav.main(["--repeats", "3"])
    print("\n== nav over zenoh: multi-process over in-process ==")
    nav.main(["--transport", "zenoh", "--repeats", "3"])
    print("\n== nav: the controller as a foreign rclpy program over built-in ==")
    foreign_nav.main(["--repeats", "3"])
    print("\n== nav: with the Foxglove live view and one client over without ==")
    live.main(["--repeats", "3"])
    print("\n== nav: where each process spends its time (py-spy) ==")
    profile.main([])
    print("\n== message cost ==")
    messages.main()
    print("\n== sensor cost ==")
    sensors.main()
    print("\n== navigation over 50 generated worlds (in-process, 2 at a time) ==")
    nav_worlds.main(["--count", "50"])
    print("\n== sweeps: 100 nav seeds in-process on every core, and on Ray ==")
    sweep.main([])


if __name__ == "__main__":
    main()
