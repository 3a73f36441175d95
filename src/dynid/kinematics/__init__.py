"""Batched geometric and kinematic models."""

from .forward import forward_kinematics, jacobian, jdot_qdot, transforms

__all__ = ["forward_kinematics", "jacobian", "jdot_qdot", "transforms"]
