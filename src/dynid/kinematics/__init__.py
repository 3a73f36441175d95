"""Batched geometric and kinematic models."""

from .forward import forward_kinematics, jacobian, transforms
from .motion import jdot_qdot, local_motion

__all__ = ["forward_kinematics", "jacobian", "jdot_qdot", "local_motion", "transforms"]
