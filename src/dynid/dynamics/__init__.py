"""Batched dynamic models: Newton-Euler, identification model, inertia matrix, base parameters."""

from .base import BaseParameters, base_parameters
from .inertia import forward_dynamics, inertia_matrix
from .model import Model
from .newton_euler import BACKENDS, Wrench, inverse_dynamics, resolve_backend
from .regressor import regressor

__all__ = [
    "BACKENDS", "BaseParameters", "Model", "Wrench", "base_parameters", "forward_dynamics", "inertia_matrix",
    "inverse_dynamics", "regressor", "resolve_backend",
]
