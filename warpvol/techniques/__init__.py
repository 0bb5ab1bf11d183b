"""One module per technique, each a ``Technique`` subclass exported as ``TECHNIQUE``."""

from . import light_shafts, raymarch, reference

TECHNIQUES = {m.TECHNIQUE.NAME: m.TECHNIQUE for m in (reference, raymarch, light_shafts)}

__all__ = ["TECHNIQUES"]
