"""The NLP of a pseudospectral Transcription evaluated with NumPy, for Ipopt through cyipopt.

Why: the PyNumero route (Pyomo's NL writer, then the ASL) walks the Pyomo expression tree of
every node to write the NL file, and the ASL then interprets one expression graph per
constraint at every evaluation. At 40k variables that is 2.4 s of hand-over and 1.7 s of
function evaluations, against CasADi's 0.1 s (reports/bench/levers.md section 17). Every
collocation node evaluates the same few functions, so here each is differentiated once by
SymPy (first and second derivatives) and evaluated for all nodes at once by NumPy; the
sparse Jacobian and Hessian are assembled with precomputed scatter indices.

This is a fast path of ``ocdsl.solve.ipopt.solve``, not a second transcription: the Pyomo
model that ``pseudospectral.build`` made stays the definition. The structure read here (which
variables, rows and coefficients) is taken from that model's variables and the mesh, the row
order is the model's constraint data, and solutions, duals and bound multipliers are loaded
back into it, so everything downstream (costates, warm starts, the certificate) is unchanged.
``DirectNLP.of`` returns ``None`` with a reason when a model is outside what it covers (extra
nonlinear constraints added after the build, an objective changed after it (mesh
refinement's regularisation), functions without a smooth NumPy form here,
an objective or boundary constraint nonlinear in an integral); the caller then takes the
PyNumero route. ``tests/test_direct_nlp.py`` checks values, Jacobians and
Hessians against PyNumero's at random points on every example in ``configs/``.

Modules: :mod:`.codegen` (smooth functions, derivatives, NumPy source and its cache, node
function families), :mod:`.structure` (what is read from the built model), :mod:`.nlp`
(:class:`DirectNLP`, cyipopt's problem object).
"""
from __future__ import annotations

from .codegen import (INF, _SMOOTH, Unsupported, _check_smooth, _function, _generated,  # noqa: F401
                      derivatives_cse)
from .nlp import DirectNLP  # noqa: F401
