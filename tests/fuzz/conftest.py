"""The fuzz suite imports the add-on tests' and native tests' helpers."""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
for folder in (HERE, HERE.parent / "native", HERE.parent / "addon"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
