"""Stage 4, finite elements: stiffness and mass assembly on P1/P2 tetrahedra, the verified
shift-invert eigensolve, the sparse direct solvers behind it, and beam theory as the analytic
reference."""

from .assembly import assemble
from .direct_solver import SOLVERS, FactorizationError, available_solvers, default_solver, factorize
from .eigen import EigenSolveError, solve_modes

__all__ = ["assemble", "EigenSolveError", "solve_modes", "SOLVERS", "FactorizationError", "available_solvers",
           "default_solver", "factorize"]
