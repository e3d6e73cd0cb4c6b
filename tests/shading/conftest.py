"""Shared set-up for the shading tests: the test folder on sys.path (cycles_oracle, compare
helpers) and bpy skipped cleanly where the wheel is missing."""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))
