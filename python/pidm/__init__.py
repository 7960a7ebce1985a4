"""pidm from Python: run scenes of the 2-DOF stick-slip piezo drive simulator and get
their maps as xarray Datasets.

The package runs the pidm binary as a child process and reads its HDF5 result
file. ``pip install ./python`` builds the binary and installs it with the package;
``$PIDM_BINARY`` overrides it, and ``pidm`` on ``PATH`` serves a package installed
without one (:func:`find_binary`). The binary must be of the package's version::

    import pidm

    ds = pidm.run({"axis": {"x": {"voltage": {"from": 0, "to": 150, "steps": 31}}}})
    (ds.step_x * 1e6).plot()            # um per drive cycle against axis.x.voltage [V]

- :func:`run`: runs a scene (a path, TOML text or a dict) and returns its maps;
- :func:`open`: reads a result file; :func:`open_trajectory` one of its
  trajectories; :func:`trajectory_names` lists them;
- :func:`check`: validates a scene and estimates its cost without running it;
- :func:`fit`: calibrates a fit scene's free keys (its ``[fit]`` table) to measured
  steps and returns a :class:`FitResult` (values, standard errors, correlations,
  the fitted scene);
- :func:`sensitivity`: Sobol' indices and the spread of a sensitivity scene's
  quantities over distributions of its keys (its ``[sensitivity]`` table) as a
  :class:`SensitivityResult` (pandas DataFrames of the indices and the spread);
- :func:`optimize`: the best values of an optimize scene's free keys (its
  ``[optimize]`` table) for an objective under constraints, or the front between
  two objectives, as an :class:`OptimizeResult` (the optimum's values, objective
  and constraints, the front as a pandas DataFrame, the scene at the optimum);
- :class:`SceneError` (a ValueError) for a scene pidm refuses, :class:`PidmError`
  for any other failure, both with pidm's message.

Units are SI as in the scene files: steps in m per own drive cycle, velocities in
m/s, voltages in V, frequencies in Hz, times in s, phases in cycles.
"""

from ._binary import BINARY_VARIABLE, find_binary
from ._errors import PidmError, SceneError
from ._fit import FitResult, FitWarning, fit
from ._optimize import OptimizeResult, OptimizeWarning, optimize
from ._read import open, open_trajectory, trajectory_names
from ._run import RunWarning, check, run
from ._sensitivity import SensitivityResult, SensitivityWarning, sensitivity
from ._toml import dumps as scene_toml
from ._version import package_version

__all__ = [
    "BINARY_VARIABLE",
    "FitResult",
    "FitWarning",
    "OptimizeResult",
    "OptimizeWarning",
    "PidmError",
    "RunWarning",
    "SceneError",
    "SensitivityResult",
    "SensitivityWarning",
    "check",
    "find_binary",
    "fit",
    "open",
    "open_trajectory",
    "optimize",
    "run",
    "scene_toml",
    "sensitivity",
    "trajectory_names",
]

__version__ = package_version()
