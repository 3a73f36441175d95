"""Vehicle simulator: the paper's car driven through standard manoeuvres, recorded by its sensors.

`CarSimulator` (car.py) integrates the car template's forward dynamics with generated,
Numba-compiled models (kernel.py, dynid.symbolic.numba_backend); `tires.py` the Magic
Formula; `manoeuvres.py` the driver's tests; `recording.py` the logged channels, files
and sidecar. Sensors: dynid.vehicle.sensors.
"""

from .car import CarSimulator, SimSettings, SimulationError, SimulationResult, sim_tree
from .manoeuvres import DEFAULTS as MANOEUVRES
from .manoeuvres import Manoeuvre, ManoeuvreError, manoeuvre, table_manoeuvre
from .tires import MagicFormula

__all__ = ["MANOEUVRES", "CarSimulator", "MagicFormula", "Manoeuvre", "ManoeuvreError", "SimSettings",
           "SimulationError", "SimulationResult", "manoeuvre", "sim_tree", "table_manoeuvre"]
