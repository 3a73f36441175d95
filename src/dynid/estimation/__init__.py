"""Estimation: one core over streamed per-group factors of [W | Y] (`StreamingLS`; a batch is one block), the
estimator as a typed value (`Method`): ordinary and weighted least squares with standard deviations (paper §5),
instrumental variables (IDIM-IV) against errors in the variables,
rank checks naming unidentifiable parameters, the %σ rule of thumb and essential parameters
(§7.2), validation errors, streaming least squares, the sensor offsets' systematic
uncertainty, and the results object.

Works on plain arrays and names: W (m, p), Y (m,), the equation group of each row, the p
parameter names. It imports nothing from the model, kinematics or dynamics layers.
"""

from .errors import EstimationWarning, IdentificationError
from .essential import RESIDUAL_TOL, EssentialResult, EssentialStep, essential_parameters
from .fit import FIT_RATIO, ModelFit, fit_note, misfit_parameters, model_fits
from .hac import HACSums
from .iv import InstrumentSums
from .lsq import LSQSolution, check_rank, solve_lsq
from .method import Covariance, CovType, Method
from .noise import SIGMA_FLOOR, GroupFit
from .ols import ols
from .quality import (
    EXCITED_FACTOR,
    POOR_FACTOR,
    not_excited,
    poorly_identified,
    relative_std_percent,
)
from .result import IdentificationResult, ResidualStats
from .streaming import StreamingLS, iv
from .systematic import BiasAccumulator, SystematicUncertainty, propagate
from .validation import nrmse, relative_errors, residual_rms
from .wls import group_noise, wls

__all__ = [
    "EXCITED_FACTOR",
    "FIT_RATIO",
    "POOR_FACTOR",
    "RESIDUAL_TOL",
    "SIGMA_FLOOR",
    "BiasAccumulator",
    "CovType",
    "Covariance",
    "EssentialResult",
    "EssentialStep",
    "EstimationWarning",
    "GroupFit",
    "HACSums",
    "IdentificationError",
    "IdentificationResult",
    "InstrumentSums",
    "LSQSolution",
    "Method",
    "ModelFit",
    "ResidualStats",
    "StreamingLS",
    "SystematicUncertainty",
    "check_rank",
    "essential_parameters",
    "fit_note",
    "group_noise",
    "iv",
    "misfit_parameters",
    "model_fits",
    "not_excited",
    "nrmse",
    "ols",
    "poorly_identified",
    "propagate",
    "relative_errors",
    "relative_std_percent",
    "residual_rms",
    "solve_lsq",
    "wls",
]
