"""`python -m addon.compare run FILE.blend --out DIR ...` and `python -m addon.compare demo --out DIR`."""
import sys

from .cli import main

sys.exit(main())
