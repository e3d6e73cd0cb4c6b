"""Shared test set-up: the repository root on sys.path so `import addon` works (the native package
is installed editable into .venv by `make venv`)."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
