"""Fast simulation layer: compiled right-hand sides and an adaptive DOP853 integrator.

Shared by the parametric search (fitness), the optimality certificate's re-integration
and closed-loop simulations.

Design choice: Numba, not C through SymPy code generation.
- The SymPy right-hand side (after ``cse``) is printed as plain Python with ``math``
  calls into a generated module, together with the integrator kernel
  (``_kernel_template.py``: Dormand-Prince 8(5,3) with the same tables, error norm and
  step control as SciPy's DOP853, Hairer's 7th-order dense output, event location by
  bisection on the dense polynomial followed by an exact landing step, batched runs
  serial, split over threads by the caller: the kernel releases the GIL). Putting RHS and
  kernel in one file makes every call a plain global call that LLVM inlines, and keeps the
  whole thing cacheable.
- Compile time: one specialisation per entry point (every array argument C-contiguous and
  writable, no literal arguments: each variant is another compilation). A double
  integrator's first PSO run compiles the single-run entry and the serial batch (about
  9 s on 2 idle cores, 38 s before, when the integrator was compiled three times and a
  ``parallel=True`` batch twice); afterwards Numba's on-disk cache (``cache=True``) loads
  a model's kernel in ~1 s. The generated module is
  written to ``$OCDSL_CACHE/simulate/ocdsl_sim_<hash>.py`` (default ``~/.cache/ocdsl``)
  with the hash of its own text, atomically, so concurrent processes (pytest-xdist
  workers, study executors, dask workers on one machine) share both the file and its
  cache; a changed model or kernel gives a new hash.
- Why not C: it needs a compiler at run time on every worker, a ctypes/cffi call per RHS
  evaluation (or the integrator in C too, i.e. a second code base), and caching a shared
  library per model by hand. Numba is one pip dependency (llvmlite wheels), keeps the
  integrator in Python syntax next to the tests, and compiles RHS + integrator together.

Sundman regularisation is a model option (``models.cr3bp.sundman``): the model is
written in s with a clock state ``time``; :func:`compile_model` detects it, controls are
evaluated at physical time and runs stop when the clock reaches the horizon.
"""
from .compile import CompiledModel, compile_model, rhs_source
from .integrate import (ControlLayout, Event, Trajectory, evaluate_controls, final_states,
                        scipy_final_state, simulate, table_coefficients)

__all__ = ["CompiledModel", "compile_model", "rhs_source", "ControlLayout", "Event",
           "Trajectory", "evaluate_controls", "final_states", "scipy_final_state",
           "simulate", "table_coefficients"]
