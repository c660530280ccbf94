"""tsim: tensegrity simulation by the tangent stiffness method.

Form-finding, substitution by real materials, vibration, folding and deployment, from a
YAML config (the `tsim` command) or from Python:

    import tsim
    r = tsim.run("configs/paper.yaml", out="runs")
    r.summary()                                 # pandas DataFrame, one row per case
    r.result("paper", stage="deployment")        # xarray Dataset of result.h5's group

A config can be a dict, and its model built from NumPy arrays with `tsim.model(...)`.
The files are those of the `tsim` command (docs/outputs.md); h5py and xarray read them.
"""

from ._api import ConfigError, Run, model, run
from ._tsim import __version__, hdf5_version

__all__ = ["ConfigError", "Run", "hdf5_version", "model", "run", "__version__"]
