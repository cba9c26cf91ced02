"""The humanoid bone map: which bone of a user's rig plays which joint (*slot*) of the model's skeleton.

The slots are the shipped model's 21 joints (Unity/VRM humanoid names with a side suffix); 15 of them are required
(:data:`REQUIRED`).  :func:`detect_bone_map` finds them in three steps:

1. **names**: every bone name is brought to a canonical form (namespaces such as ``mixamorig:``/``Armature|`` and
   prefixes such as ``DEF-``/``CC_Base_``/``Bip01 ``/``J_Bip_L_`` stripped, camelCase and ``_ . - space`` split, the
   side tokens ``L/R/Left/Right/左/右`` taken out as a side), then scored against naming presets (the model's own
   names, Mixamo/LAFAN1, CMU, UE4/UE5 mannequin, Rigify meta-rig and deform bones, SMPL, Poser, DAZ, MakeHuman,
   VRM/VRoid, 3ds Max Biped, Character Creator, MMD, and a generic vocabulary).  One preset is chosen for the whole
   rig, the one that maps the most required slots consistently with the hierarchy and explains the most bones, so
   an ambiguous name is read the way its rig means it ("LeftShoulder" is the clavicle next to "LeftArm", the upper
   arm next to "LeftCollar");
2. **structure**, for the slots the names leave empty: the hierarchy and the rest offsets (any up axis, any unit):
   legs and arms are the two mirrored pairs of big branches, the hips where the legs branch off, the spine the path
   up to the arms, the head the chain above it; elbows and knees by their place along the limb, feet where the
   limb turns forward, left and right from the rest pose (forward = where the toes point);
3. **override**: ``{rig_bone: slot}`` (a YAML file, :func:`read_override`) on top; ``null`` unmaps a bone.

A rig that cannot be mapped raises :class:`BoneMapError` (one line naming the missing slots) with an override
template in ``.template``.

Standard library and numpy only (PyYAML imported inside :func:`read_override`): the Blender extension bundles this
package without PyTorch.  The modules, each importing only those above it:

- :mod:`.slots`: the slots (:data:`SLOTS`, :data:`SLOT_PARENTS`, :data:`REQUIRED`, :data:`OPTIONAL`) and
  :class:`BoneMapError`;
- :mod:`.names`: canonical bone names (:func:`canonical`) and the naming presets (:data:`PRESETS`);
- :mod:`.rig`: the rig (hierarchy, rest positions, canonical names) and the checks of slots against its hierarchy;
- :mod:`.name_pass`: step 1, the slots the names give under the best preset;
- :mod:`.structure`: step 2, the structural fallback and its merge with the names;
- :mod:`.detect`: :class:`BoneMap`, the override template, :func:`read_override` and :func:`detect_bone_map`.
"""
from __future__ import annotations

from .detect import BoneMap, detect_bone_map, read_override
from .names import PRESETS, canonical
from .slots import OPTIONAL, REQUIRED, SLOT_PARENTS, SLOTS, BoneMapError

__all__ = [
    "OPTIONAL",
    "PRESETS",
    "REQUIRED",
    "SLOTS",
    "SLOT_PARENTS",
    "BoneMap",
    "BoneMapError",
    "canonical",
    "detect_bone_map",
    "read_override",
]
