"""Regenerate ocdsl/solve/ipopt_options.txt: the option names the bundled Ipopt knows.

Ipopt prints its option documentation on stdout from C, so run this as a script and
redirect: python scripts/ipopt_option_names.py > /tmp/doc.txt, then keep the names.
"""
import numpy as np

import cyipopt


class _Tiny:
    def objective(self, x):
        return float(x[0] ** 2)

    def gradient(self, x):
        return np.array([2 * x[0]])

    def constraints(self, x):
        return np.zeros(0)

    def jacobian(self, x):
        return np.zeros(0)


if __name__ == "__main__":
    nlp = cyipopt.Problem(n=1, m=0, problem_obj=_Tiny(), lb=[-1.0], ub=[1.0], cl=[], cu=[])
    nlp.add_option("print_options_documentation", "yes")
    nlp.add_option("print_advanced_options", "yes")
    nlp.add_option("hessian_approximation", "limited-memory")
    nlp.solve(np.array([0.5]))
