"""The live side of a run: the live view's endpoints (Foxglove, rosbridge), the follower of
the recording they read, and the mirror of zenoh traffic onto DDS."""
