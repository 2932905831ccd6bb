"""The plumbing of the compiled (numba) kernels, the package's lowest layer: a writable cache folder for their machine
code (:mod:`~arap.kernels.cache`) and the thread policy and lock of their parallel launches
(:mod:`~arap.kernels.parallel`). Every module that defines a kernel imports :mod:`arap.kernels.cache` first; this
layer imports nothing else of arap."""
