"""Pictures of meshes without a browser: a software rasteriser in NumPy (:mod:`arap.render.camera`,
:mod:`arap.render.raster`), a PNG encoder (:mod:`arap.render.png`), the :class:`~arap.render.picture.Picture` it makes,
and :func:`arap.render.show.show`, exported as ``arap.show``.

Example
-------
>>> import arap
>>> arap.show("sphere:100", width=32, height=24).pixels.shape
(24, 32, 3)
"""
