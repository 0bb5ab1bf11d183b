"""Pure physics as ``@wp.func``: phase functions, transmittance, lights, sphere directions,
the Sun et al. 2005 airlight. Nothing here knows about scenes."""

from . import airlight, brdf, constants, lights, phase, sphere, transmittance

__all__ = ["airlight", "brdf", "constants", "lights", "phase", "sphere", "transmittance"]
