"""Stages, their inputs, and what a change invalidates; Frames and validated settings.

A technique is a small graph of named stages (upload the medium, bake a shadow volume,
march, ...). Each ``Stage`` declares what it reads: scene parts (``PARTS``), settings by
name, and the stages whose outputs it uses. ``Pipeline`` runs a frame:

* a stage the scene does not call for (``needed=False``: no surfaces, no shadow pass;
  single scattering, no iteration) is **skipped**;
* a stage whose inputs are unchanged since it last ran is **cached**: its outputs, kept
  by the technique, are used again;
* every other stage **ran**, timed with the device synchronised after it.

A change is a version bump of a scene part: ``Pipeline.update`` bumps what it replaces,
and a part marked ``static = false`` in the scene is treated as changed every frame
(animated). A stage's cache key is the versions of the parts it reads, the values of the
settings it reads and the run counts of the stages it follows, so a re-run propagates
downstream and nothing else. This is the rule of Giroud & Biri 2011, Table 1.

The package: ``settings`` (Setting, resolve_settings, SettingsError, Quality, Bias),
``technique`` (Technique, Stage, StageRun, PARTS), ``frame`` (Frame) and ``graph`` (Pipeline).
"""

from .frame import Frame
from .graph import Pipeline, dynamic_parts
from .settings import FLAG, Bias, Quality, Setting, SettingsError, resolve_settings
from .technique import PARTS, Stage, StageRun, Technique, has_sky

__all__ = ["FLAG", "PARTS", "Bias", "Frame", "Pipeline", "Quality", "Setting", "SettingsError", "Stage", "StageRun",
           "Technique", "dynamic_parts", "has_sky", "resolve_settings"]
