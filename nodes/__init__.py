"""cosim nodes: pure step classes, and the runtime that alone touches a transport."""
