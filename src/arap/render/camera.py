"""The camera of :func:`arap.show`: an orthographic view of a mesh from an azimuth and an elevation, fitted to the
mesh's extent on screen. +y is up, as in the studio; azimuth 0 and elevation 0 look at the mesh from +z towards -z,
a positive azimuth turns the viewer towards +x and a positive elevation lifts it above the mesh. A :class:`Camera`
maps points to pixel coordinates (x to the right, y downwards, pixel ``(i, j)`` covering ``[j, j + 1) x [i, i + 1)``)
and a depth that grows away from the viewer; the same camera can picture several shapes (a mesh and its deformation)
at the same scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError

__all__ = ["DEFAULT_AZIMUTH", "DEFAULT_ELEVATION", "MAX_SIDE", "Camera", "check_size", "fit_camera", "view_basis"]

#: The default view: a three-quarter front view from the right and above.
DEFAULT_AZIMUTH, DEFAULT_ELEVATION = 30.0, 20.0

#: The largest width or height of a picture, in pixels (an anti-aliased picture of 4096 x 4096 pixels takes about
#: 2 GB while it is drawn).
MAX_SIDE = 4096

#: Share of the picture left free on each side when a camera is fitted.
MARGIN = 0.05


def check_size(width: object, height: object) -> tuple[int, int]:
    """The picture size as two ints from 1 to :data:`MAX_SIDE`.

    Raises
    ------
    OptionError
        Not whole numbers, or out of range.

    Example
    -------
    >>> check_size(640, 480)
    (640, 480)
    """
    sides = []
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise OptionError(f"{name} must be a whole number of pixels, got {value!r}")
        if not 1 <= int(value) <= MAX_SIDE:
            raise OptionError(f"{name} must be from 1 to {MAX_SIDE} pixels, got {int(value)}")
        sides.append(int(value))
    return sides[0], sides[1]


def _angle(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise OptionError(f"{name} must be a number of degrees, got {value!r}")
    if not math.isfinite(float(value)):
        raise OptionError(f"{name} must be a finite number of degrees, got {value!r}")
    return float(value)


def view_basis(azimuth: float, elevation: float) -> NDArray[np.float64]:
    """The camera's axes as the rows of a (3, 3) array: right, up, and towards the viewer.

    Example
    -------
    >>> (view_basis(0.0, 0.0).round(12) + 0.0).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    az = math.radians(_angle("azimuth", azimuth))
    el = math.radians(_angle("elevation", elevation))
    back = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    right = np.array([math.cos(az), 0.0, -math.sin(az)])  # horizontal, even looking straight down or up
    up = np.cross(back, right)
    return np.array([right, up / np.linalg.norm(up), back])


@dataclass(frozen=True)
class Camera:
    """An orthographic camera.

    Attributes
    ----------
    basis : (3, 3) float64 array
        Rows: the right, up and backward (towards the viewer) directions in mesh coordinates.
    center : (3,) float64 array
        The point shown at the middle of the picture.
    scale : float
        Pixels per mesh unit.
    width, height : int
        Picture size in pixels.
    """

    basis: NDArray[np.float64]
    center: NDArray[np.float64]
    scale: float
    width: int
    height: int

    @property
    def toward_viewer(self) -> NDArray[np.float64]:
        """(3,) unit vector from the mesh towards the viewer (the headlight's direction)."""
        return self.basis[2]

    def project(self, V: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixel coordinates and depth of points.

        Parameters
        ----------
        V : (n, 3) float array

        Returns
        -------
        (n, 3) float64 array
            x (to the right) and y (downwards) in pixels, and the depth in mesh units (larger is farther).

        Example
        -------
        >>> cam = Camera(view_basis(0, 0), np.zeros(3), 10.0, 100, 50)
        >>> cam.project(np.array([[0.0, 0, 0], [1, 1, 1]])).tolist()
        [[50.0, 25.0, 0.0], [60.0, 15.0, -1.0]]
        """
        local = (np.asarray(V, dtype=np.float64) - self.center) @ self.basis.T
        out = np.empty_like(local)
        out[:, 0] = 0.5 * self.width + self.scale * local[:, 0]
        out[:, 1] = 0.5 * self.height - self.scale * local[:, 1]
        out[:, 2] = 0.0 - local[:, 2]
        return out

    def scaled(self, factor: int) -> Camera:
        """The same view on a picture ``factor`` times larger each way (for supersampling)."""
        return Camera(self.basis, self.center, self.scale * factor, self.width * factor, self.height * factor)


def fit_camera(V: NDArray[np.float64], width: int = 640, height: int = 480, *, azimuth: float = DEFAULT_AZIMUTH,
               elevation: float = DEFAULT_ELEVATION, margin: float = MARGIN) -> Camera:
    """The camera that shows the points ``V`` from a direction, as large as the picture allows.

    Parameters
    ----------
    V : (n, 3) float array
        Points to frame (n >= 1, finite).
    width, height : int
        Picture size in pixels.
    azimuth, elevation : float
        Viewing direction in degrees (see the module description).
    margin : float
        Share of the picture left free on each side.

    Returns
    -------
    Camera
        Centred on the middle of the points' extent on screen.

    Example
    -------
    >>> V = np.array([[-1.0, -1, 0], [1, 1, 0]])
    >>> cam = fit_camera(V, 100, 100, azimuth=0, elevation=0, margin=0.0)
    >>> cam.project(V)[:, :2].tolist()
    [[0.0, 100.0], [100.0, 0.0]]
    """
    width, height = check_size(width, height)
    basis = view_basis(azimuth, elevation)
    local = np.asarray(V, dtype=np.float64) @ basis[:2].T
    lo, hi = local.min(axis=0), local.max(axis=0)
    mid = 0.5 * (lo + hi)
    extent = hi - lo
    room = max(1.0 - 2.0 * margin, 1e-3)
    fits = [room * side / e for side, e in ((width, extent[0]), (height, extent[1])) if e > 0]
    scale = min(fits) if fits else 1.0
    center = basis[0] * mid[0] + basis[1] * mid[1]  # on the plane through the origin facing the viewer
    return Camera(basis, center, float(scale), width, height)
