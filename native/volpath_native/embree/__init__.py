"""A direct binding of the Embree 4 library that embreex ships: scenes over shared buffers,
instances, motion steps, and compiled bulk queries (library.py, scene.py, queries.py)."""
from .scene import EmbreeError, TriangleScene  # noqa: F401
