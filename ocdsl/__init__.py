"""ocdsl: declarative optimal control, from YAML problem files to verified trajectories."""
import os as _os
import sys as _sys

# PyNumero's ASL library is built into the environment (make setup); point Pyomo at it
# before Pyomo is imported anywhere, unless the user chose another place.
_cfg = _os.path.join(_sys.prefix, "share", "pyomo")
if "PYOMO_CONFIG_DIR" not in _os.environ and _os.path.isdir(_cfg):
    _os.environ["PYOMO_CONFIG_DIR"] = _cfg

__version__ = "0.1.0"


def load(path, parameters=None):
    """Load and compile a problem file; ``.solve()`` it to get a Result."""
    from .api import load as _load

    return _load(path, parameters)


def read(run_dir):
    """The Result of a run folder (what ``ocdsl run`` or ``Result.write`` left), with the same
    API as a fresh solve: ``res.sample(t)``, ``res.to_pandas()``, ``res.plot()``, ``res.summary()``."""
    from .result import Result

    return Result.read(run_dir)


__all__ = ["load", "read", "__version__"]
