"""cosim nodes: pure step classes, and the runtime that alone touches a transport.

Importing this package provides its node kinds to the plan (``nodes.registry``)."""

import nodes.registry  # noqa: F401 - provides the catalogue of kinds to plan.kinds
