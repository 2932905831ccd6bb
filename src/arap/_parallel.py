"""Serialises calls into the parallel compiled kernels.

numba's default threading layer must not be entered from two Python threads at once (the studio solves several
sessions on worker threads). With two cores there is nothing to gain from overlapping kernels, so one lock guards
every parallel kernel launch; sparse solves and everything else still run concurrently.
"""

from __future__ import annotations

import threading

kernel_lock = threading.Lock()
