"""Example scenes built from bpy calls only; each module has `build()` and `python examples/X.py OUT.blend`."""
