"""Parameter types the controllers' models share, as generate_parameter_library's
validators declare them upstream (``not_empty<>``, ``unique<>``, ``fixed_size<>``)."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, Field


def _unique(names: list[str]) -> list[str]:
    if len(set(names)) != len(names):
        raise ValueError("names a joint twice; unique joint names")
    return names


JOINTS_HELP = "a list of joint names, e.g. [joint_1, joint_2]"
JointNames = Annotated[list[str], Field(min_length=1, description=JOINTS_HELP),
                       AfterValidator(_unique)]
"""A required, non-empty list of unique joint names."""
OptionalJointNames = Annotated[list[str], Field(description=JOINTS_HELP),
                               AfterValidator(_unique)]
"""A list of unique joint names, possibly empty."""
Covariance = Annotated[list[float], Field(min_length=6, max_length=6, description=(
    "[xx, yy, zz, rr, pp, yy], e.g. [0.001, 0.001, 0.001, 0.001, 0.001, 0.01]"))]
"""The six diagonal entries of a 6x6 covariance."""
