"""Small purpose-built MJCF worlds for the node unit tests (written to a tmp_path)."""

from __future__ import annotations

from pathlib import Path

ROBOT = Path(__file__).resolve().parents[1] / "scenarios" / "worlds" / "robot.xml"


def write_world(tmp_path: Path, obstacles: str = "", timestep: str = "0.002") -> Path:
    """A floor, the cosim robot (copied next to it) and the given obstacle geoms."""
    (tmp_path / "robot.xml").write_text(ROBOT.read_text())
    world = tmp_path / "world.xml"
    world.write_text(f"""<mujoco model="test">
  <option timestep="{timestep}" integrator="implicitfast"/>
  <visual><quality shadowsize="0"/><map znear="0.01" zfar="50"/></visual>
  <include file="robot.xml"/>
  <worldbody>
    <light pos="0 0 5" dir="0 0 -1" directional="true" castshadow="false"/>
    <geom name="floor" type="plane" size="20 20 0.1"/>
    {obstacles}
  </worldbody>
</mujoco>
""")
    return world
