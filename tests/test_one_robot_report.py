"""One robot in a ``robots:`` section (a user's robot doing nav's task, scenarios/nav_urdf.yaml)
gets nav's report: the map with its plan, path, lidar returns and goal, and its speed, turn
rate and distances over time, read from the robot's topics (at the root: it is alone)."""

from __future__ import annotations

from matplotlib import image

from descriptions.load import load_scenario
from orchestrator.outputs.picture import DPI, report_figure
from tests.helpers import ROOT, orchestrate

NAV_URDF = ROOT / "scenarios" / "nav_urdf.yaml"


def test_one_robot_of_a_robots_section_gets_navs_report(tmp_path):
    run = orchestrate(NAV_URDF, tmp_path, "--in-process", "--quiet", "--duration", "4s",
                      picture=True)
    assert run.code == 1, run.stderr  # goal not met in 4 s: the picture is what counts here
    height, width = image.imread(run.run_dir / "report.png").shape[:2]
    assert (width, height) == (15 * DPI, round(9.5 * DPI))  # nav's figure, not the swarm's
    fig = report_figure(load_scenario(NAV_URDF), run.run_dir / "bag")
    panels = [ax.get_ylabel() for ax in fig.axes]
    assert {"speed [m/s]", "turn rate [rad/s]", "distance [m]"} <= set(panels)
    labels = [label for ax in fig.axes for label in ax.get_legend_handles_labels()[1]]
    assert "goal (3.00, 3.00), tolerance 0.25 m" in labels  # the robot's goal
    assert "lidar returns at 0.0 s" in labels and "nearest lidar return" in labels
    assert "start (-3.00, -3.00)" in labels and "/cmd_vel linear.x" in labels
