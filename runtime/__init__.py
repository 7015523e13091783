"""The machinery that runs step nodes for a transport: the lockstep and realtime runtimes,
the protocol, message exchange and recording, CDR code and the transports. Only code under
this package touches a transport; the node kinds beside it are pure step classes."""
