"""One module per technique, each a ``Technique`` subclass exported as ``TECHNIQUE``."""

from . import raymarch, reference

TECHNIQUES = {m.TECHNIQUE.NAME: m.TECHNIQUE for m in (reference, raymarch)}

__all__ = ["TECHNIQUES"]
