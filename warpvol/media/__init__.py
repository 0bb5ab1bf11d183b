"""Turning a scene's media into what kernels read."""

from .volume import Media, MediaBuffers

__all__ = ["Media", "MediaBuffers"]
