"""Blender shader node trees evaluated in the kernels: the program format (program.py), its one
interpreter (interpreter.py) and the texture nodes (textures/). See program.py."""
