"""Make the toy disciplines importable as ``sellar:Class`` from test configs."""
import sys
from pathlib import Path

HERE = str(Path(__file__).resolve().parent)
if HERE not in sys.path:
    sys.path.insert(0, HERE)
