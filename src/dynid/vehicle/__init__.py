"""The paper's car: 42-frame template, parameter sets, kinematic tables, aerodynamics, statics,
the identification equations and their base parameters (frame conventions: template.py; frame numbers:
dynid.car_frames); how its results are judged and laid out (presentation.py) and what its run and report say
in words (notes.py)."""

from .aero import Aerodynamics, AeroError, aero_wrench
from .car_model import car_template
from .equations import CarEquations, CarResidual, car_base_parameters, car_identification
from .geometry import AxleGeometry, CarGeometry, GeometryError
from .parameters import ParameterSet, a_priori, paper_estimates, truth
from .statics import RestState, design_preloads, rest_state
from .tables import KinematicTable, KinematicTableError, KinematicTables, default_tables, load_table_csv, load_tables
from .template import CORNERS, DAMPERS, EQUATION_ROWS, TIRES, WHEELS, paper_parameter_names

__all__ = [
    "CORNERS", "DAMPERS", "EQUATION_ROWS", "TIRES", "WHEELS", "AeroError", "Aerodynamics", "AxleGeometry",
    "CarEquations", "CarGeometry", "CarResidual", "GeometryError", "KinematicTable", "KinematicTableError",
    "KinematicTables", "ParameterSet", "RestState", "a_priori", "aero_wrench", "car_base_parameters",
    "car_identification", "car_template", "default_tables", "design_preloads", "load_table_csv", "load_tables",
    "paper_estimates", "paper_parameter_names", "rest_state", "truth",
]
