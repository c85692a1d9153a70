"""A tiny test-only problem whose solver crashes, hangs or fails on chosen guesses (multistart tests).

Loaded by the spawned workers through the ``"module:Class"`` problem hook, so it lives in an importable
module rather than inside a test function.  Decision vector: one variable ``x`` in [0, 10]; the solve
"converges" to round(x); x = 3.5 kills the worker process, x = 4.5 sleeps forever, x = 5.5 raises.
"""

import os
import time

import numpy as np

from amorgs.problems.base import SolveRecord, check_vector


class CrashyProblem:
    name = "crashy"
    variable_names = ("x",)
    lower = np.array([0.0])
    upper = np.array([10.0])
    alpha_range = (0.0, 1.0)

    def sample_uniform(self, alpha, n, rng):
        return rng.uniform(0.0, 10.0, (n, 1))

    def check_guess(self, x):
        return check_vector(x, self.variable_names, self.lower, self.upper, self.name)

    def make_local_solver(self, options=None):
        return self

    def solve(self, x0, alpha):
        x = float(x0[0])
        if x == 3.5:
            os._exit(3)
        if x == 4.5:
            time.sleep(3600)
        if x == 5.5:
            raise ZeroDivisionError("boom")
        return SolveRecord(status="ok", converged=True, solver_success=True, x=np.array([round(x)]),
                           objective=float(round(x)), iterations=1, wall_s=0.0, cpu_s=0.0)
