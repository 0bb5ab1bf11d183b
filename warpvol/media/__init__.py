"""What kernels read of the media: the ``Media`` struct and its lookups (built by ``warpvol.upload``)."""

from .volume import Media

__all__ = ["Media"]
