"""The live view (``--live``, ``--rosbridge``, a digital twin's link) as one attachment of the
run (``orchestrator.drivers.face.Attachment``): the same for every driver.

- nodes starting: with ``--live``, the schemas of the run's topics are built meanwhile;
- serving: the endpoints start (a failure to listen fails the run) and the run's simulation
  services' schemas are built meanwhile; the endpoints close with the run, and what they
  did goes into the outcome;
- ready: the run's simulation services are offered, and the driver feeds the run's traffic
  to the endpoints.

Nothing here imports rclpy at module level: ``orchestrator.live.view`` is imported once the
nodes are started.
"""

from __future__ import annotations

from plan.errors import SimulationError


class LiveView:
    """The run's live endpoints, started and fed through the driver's face."""

    def __init__(self):
        self.endpoints = None

    def nodes_starting(self, ctx) -> None:
        """With ``--live``: build the topics' schemas while the nodes start."""
        if ctx.options.live:
            from orchestrator.live.view import prepare_schemas

            prepare_schemas(ctx.scenario, ctx.options)

    def serving(self, ctx, driver) -> None:
        """Start the endpoints the options ask for (none: nothing more to do)."""
        from orchestrator.live.view import prepare_control, start_endpoints
        from runtime.live.session import LiveError

        try:
            self.endpoints = start_endpoints(ctx.scenario, ctx.options, ctx.external,
                                             driver.control_later)
        except LiveError as exc:
            raise SimulationError(str(exc), node="orchestrator") from exc
        if self.endpoints is None:
            return
        ctx.resources.callback(self._close, ctx.outcome)
        prepare_control(self.endpoints, ctx.services)

    def ready(self, ctx, driver) -> None:
        """Offer the run's simulation services and its traffic."""
        if self.endpoints is None:
            return
        from orchestrator.live.view import attach_control

        attach_control(self.endpoints, ctx.services)
        driver.feed(ctx, self.endpoints.offer)

    def _close(self, outcome) -> None:
        """Stop the endpoints and keep what they did."""
        outcome.live = self.endpoints.close()
