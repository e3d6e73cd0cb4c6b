"""Cycles' texture nodes as scalar numba functions (Noise, Voronoi, Gradient, Wave, Magic, White
Noise), bit-exact where the image depends on it, and their opcodes (ops.py)."""
