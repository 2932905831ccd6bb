"""The mesh layer: checks of vertex and face arrays, repair (welding, degenerate faces), topology (adjacency,
components, locality orders), built-in shapes and diagnostics of a mesh.
"""
