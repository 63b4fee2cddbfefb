"""Stage 4, finite elements: stiffness and mass assembly on P1/P2 tetrahedra, the verified
shift-invert eigensolve, and beam theory as the analytic reference."""

from .assembly import assemble
from .eigen import EigenSolveError, solve_modes

__all__ = ["assemble", "EigenSolveError", "solve_modes"]
