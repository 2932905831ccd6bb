"""Exceptions raised by arap.

Every error the library raises on bad input derives from :class:`ArapError` (itself a ``ValueError``), so callers
can catch one type, while the subclasses let them tell what went wrong.
"""

from __future__ import annotations


class ArapError(ValueError):
    """Base class of every input error raised by arap.

    Examples
    --------
    >>> import numpy as np, arap
    >>> try:
    ...     arap.check_mesh(np.zeros((3, 3)), np.array([[0, 1, 5]]))
    ... except arap.ArapError as error:                       # any input error of arap
    ...     print(type(error).__name__, isinstance(error, ValueError))
    MeshError True
    """


class OptionError(ArapError):
    """An option names no known choice or is out of range: an energy, weights, start, acceleration, backend or
    ordering name, or the size of a built-in shape.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> try:
    ...     arap.ArapSolver(V, F, [0], energy="springs")
    ... except arap.OptionError as error:
    ...     print(type(error).__name__)
    OptionError
    """


class MeshError(ArapError):
    """The mesh itself is unusable: wrong shapes, non-finite coordinates, bad or degenerate faces.

    Examples
    --------
    >>> import numpy as np, arap
    >>> try:
    ...     arap.check_mesh(np.zeros((3, 3)), np.array([[0, 1, 5]]))   # vertex 5 does not exist
    ... except arap.MeshError as error:
    ...     print(type(error).__name__)
    MeshError
    """


class ConstraintError(ArapError):
    """The constraints are unusable: indices out of range or repeated, targets of the wrong shape or non-finite.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> try:
    ...     arap.ArapSolver(V, F, [0, 100])                  # the sphere has 42 vertices
    ... except arap.ConstraintError as error:
    ...     print(type(error).__name__)
    ConstraintError
    """


class UnconstrainedRegionError(ConstraintError):
    """A connected part of the free vertices touches no constrained vertex, so its linear system is singular.

    Attributes
    ----------
    vertices : list[int]
        A few vertex indices of the offending part (for the message and for tools that highlight it).
    size : int
        Number of free vertices in that part.

    Examples
    --------
    Two separate triangles, only one of them held:

    >>> import numpy as np, arap
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], dtype=float)
    >>> F = np.array([[0, 1, 2], [3, 4, 5]])
    >>> try:
    ...     arap.ArapSolver(V, F, [0])
    ... except arap.UnconstrainedRegionError as error:
    ...     print(error.size, error.vertices)
    3 [3, 4, 5]
    """

    def __init__(self, message: str, vertices: list[int], size: int) -> None:
        super().__init__(message)
        self.vertices = vertices
        self.size = size


class MeshFormatError(MeshError):
    """A mesh file could not be read or written (unknown extension, unreadable file, binary junk, unparsable
    content); a kind of :class:`MeshError`, since the mesh it should hold is unusable.

    Examples
    --------
    >>> import arap
    >>> try:
    ...     arap.load_mesh_bytes(b"not a mesh", "stl")
    ... except arap.MeshFormatError as error:
    ...     print(type(error).__name__)
    MeshFormatError
    """


class MeshTooLargeError(MeshFormatError):
    """A mesh file holds more vertices (or, for STL soups, more triangles) than the caller accepts.

    Attributes
    ----------
    count : int
        Vertices the file holds (for STL: the vertices its triangles need at the least).
    limit : int
        Largest accepted vertex count.

    Examples
    --------
    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "sphere.off")
    ...     arap.save_mesh(path, *arap.sphere(1))
    ...     try:
    ...         arap.load_mesh_with_report(path, max_vertices=10)
    ...     except arap.MeshTooLargeError as error:
    ...         print(error.count, error.limit)
    42 10
    """

    def __init__(self, message: str, count: int, limit: int) -> None:
        super().__init__(message)
        self.count = count
        self.limit = limit
