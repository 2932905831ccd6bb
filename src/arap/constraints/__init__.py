"""Constraints: the constraints document (anchors, handle groups, region of interest, stiffness, point handles,
keyframes), selections and their checks, vertices chosen by position, and the scenarios the tests and benchmarks
use. The document's API is re-exported here.
"""

from arap.constraints.document import *  # noqa: F403
from arap.constraints.document import __all__ as __all__
