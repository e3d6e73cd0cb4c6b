"""Compare VolPath with Cycles: statistics (metrics), contact sheets (sheet), reports (report), the
engines' matched runs (cycles_engine, volpath_engine), the runner (compare_scene / compare_file),
the Blender operator `volpath.compare_with_cycles` and the headless CLI (`python -m addon.compare`).

Registered by the add-on's __init__ through register() / unregister().
"""


def register():
    from . import operator
    operator.register()


def unregister():
    from . import operator
    operator.unregister()
