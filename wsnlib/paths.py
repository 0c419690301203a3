"""Project folders, built from this package's location (never from the working directory)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"
DATA_RAW = ROOT / "data" / "raw"
DATA_PROCESSED = ROOT / "data" / "processed"
FIGURES = ROOT / "figures"
EXECUTED = ROOT / "build" / "executed"

#: Name of the Jupyter kernel that ``make`` registers for the project's virtual environment.
KERNEL_NAME = "wsn-motion"
