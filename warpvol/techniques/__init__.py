"""One module per technique, each a ``Technique`` subclass exported as ``TECHNIQUE``."""

from . import depth_impostors, illumination_network, light_shafts, raymarch, rbf_propagation, reference

TECHNIQUES = {m.TECHNIQUE.NAME: m.TECHNIQUE for m in (reference, raymarch, light_shafts, rbf_propagation, illumination_network,
                                             depth_impostors)}

__all__ = ["TECHNIQUES"]
