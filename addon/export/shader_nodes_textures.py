"""Compile functions of the texture nodes (filled in by the textures work): node.type -> fn(c, node)."""
TEXTURE_NODE_COMPILERS: dict = {}
