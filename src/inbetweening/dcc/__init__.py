"""The DCC core: what every front end of the fill runtime in an animation package (Blender, Maya, a game engine's
editor) needs, whatever the host.

It sits between the fill runtime (:mod:`inbetweening.runtime`: keys in, the filled motion out) and a front end, which
keeps only what is the host's: reading and writing curves and keys, the UI, operators and undo.  The core holds:

- which frames are keys, whole and partial (:mod:`.keys`), and the hand edits since the last fill, kept exactly
  (:mod:`.edits`);
- the record of the last fill and the re-fill plan it gives: only the gaps whose inputs changed are re-filled
  (:mod:`.record`), and what the model did per gap (:mod:`.report`);
- the rig kinds: the model's own skeleton, filled directly, and any humanoid, through the bone map and retargeting
  (:mod:`.mapped`);
- the whole "fill this action" flow (:func:`~.fill.fill_action`),

behind a small rig interface a front end implements (:mod:`.host`: :class:`Curves`, the host's keys; :class:`Rig`,
the rig's poses; :class:`MappedRig` for any humanoid).  The Blender extension is one such front end
(``inbetweening/blender/extension``); ``tests/test_dcc_loop.py`` drives the core through an in-memory host.

numpy and the runtime only: no PyTorch, no host module; the Blender extension bundles this package with the runtime
(``python -m inbetweening.blender build``).
"""
from __future__ import annotations

from .fill import fill_action
from .host import Channel, Curves, Keys, Rig, RigError
from .mapped import MappedRig, is_model_skeleton

__all__ = ["Channel", "Curves", "Keys", "MappedRig", "Rig", "RigError", "fill_action", "is_model_skeleton"]
