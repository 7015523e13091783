"""The lockstep loop: the master that grants ticks and collects acknowledgements, the participants
it drives, the in-process driver (the reference run) and the supervisor of the node processes."""
