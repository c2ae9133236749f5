"""Multidisciplinary analysis: ``MDA`` (analysis.py) runs a batch through the coupling graph and
hands each feedback loop to a loop solver chosen by name from ``SOLVERS``: one module per solver
(gauss_seidel.py, jacobi.py, newton.py) behind ``base.LoopSolver``. A failed point carries an
``MDAError`` (discipline, point, kind, message)."""
from bev_mdo.mdo.mda.analysis import METHODS, MDA, SOLVERS
from bev_mdo.mdo.mda.base import KINDS, LoopSolver, MDAError, MDAResult
from bev_mdo.mdo.mda.newton import FD_STEP

__all__ = ["FD_STEP", "KINDS", "LoopSolver", "MDA", "MDAError", "MDAResult", "METHODS", "SOLVERS"]
