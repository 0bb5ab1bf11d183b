"""One module per technique, each a ``Technique`` subclass exported as ``TECHNIQUE``."""

from . import depth_impostors, illumination_network, light_shafts, particle_glow, raymarch, rbf_propagation, reference

TECHNIQUES = {m.TECHNIQUE.NAME: m.TECHNIQUE for m in (reference, raymarch, light_shafts, rbf_propagation, illumination_network,
                                             depth_impostors, particle_glow)}

__all__ = ["TECHNIQUES"]
