"""Exceptions raised by arap.

Every error the library raises on bad input derives from :class:`ArapError` (itself a ``ValueError``), so callers
can catch one type, while the subclasses let them tell what went wrong.
"""

from __future__ import annotations


class ArapError(ValueError):
    """Base class of every input error raised by arap."""


class OptionError(ArapError):
    """An option names no known choice or is out of range: an energy, weights, start, acceleration, backend or
    ordering name, or the size of a built-in shape."""


class MeshError(ArapError):
    """The mesh itself is unusable: wrong shapes, non-finite coordinates, bad or degenerate faces."""


class ConstraintError(ArapError):
    """The constraints are unusable: indices out of range or repeated, targets of the wrong shape or non-finite."""


class UnconstrainedRegionError(ConstraintError):
    """A connected part of the free vertices touches no constrained vertex, so its linear system is singular.

    Attributes
    ----------
    vertices : list[int]
        A few vertex indices of the offending part (for the message and for tools that highlight it).
    size : int
        Number of free vertices in that part.
    """

    def __init__(self, message: str, vertices: list[int], size: int) -> None:
        super().__init__(message)
        self.vertices = vertices
        self.size = size


class MeshFormatError(MeshError):
    """A mesh file could not be read or written (unknown extension, unreadable file, binary junk, unparsable
    content); a kind of :class:`MeshError`, since the mesh it should hold is unusable."""


class MeshTooLargeError(MeshFormatError):
    """A mesh file holds more vertices (or, for STL soups, more triangles) than the caller accepts.

    Attributes
    ----------
    count : int
        Vertices the file holds (for STL: the vertices its triangles need at the least).
    limit : int
        Largest accepted vertex count.
    """

    def __init__(self, message: str, count: int, limit: int) -> None:
        super().__init__(message)
        self.count = count
        self.limit = limit
