"""Batched dynamic models: Newton-Euler, identification model, inertia matrix, base parameters."""

from .base import BaseParameters, base_parameters
from .inertia import forward_dynamics, inertia_matrix
from .model import Model, load_model
from .newton_euler import BACKENDS, Wrench, inverse_dynamics, resolve_backend
from .regressor import regressor

__all__ = [
    "BACKENDS", "BaseParameters", "Model", "Wrench", "base_parameters", "forward_dynamics", "inertia_matrix",
    "inverse_dynamics", "load_model", "regressor", "resolve_backend",
]
