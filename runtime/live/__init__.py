"""Watching and driving a run from outside: a Foxglove WebSocket live view and a rosbridge v2
server. The producer (the orchestrator's master loop, or a realtime node's loop) only ever
offers messages to bounded per-channel queues; the servers run in threads of their own, so a
slow or stuck client can neither slow the run nor grow memory without bound."""
