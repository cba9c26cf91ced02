"""The slots (the model's joints a rig's bones are mapped onto), their parents, which are required, and
:class:`BoneMapError`."""
from __future__ import annotations

SLOTS: tuple[str, ...] = (
    "Hips", "Spine", "Chest", "Neck", "Head",
    "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L",
    "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R",
    "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
    "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R",
)
SLOT_PARENTS: dict[str, str | None] = {
    "Hips": None, "Spine": "Hips", "Chest": "Spine", "Neck": "Chest", "Head": "Neck",
    **{f"{part}_{s}": parent for s in "LR" for part, parent in (
        ("Shoulder", "Chest"), ("UpperArm", f"Shoulder_{s}"), ("LowerArm", f"UpperArm_{s}"), ("Hand", f"LowerArm_{s}"),
        ("UpperLeg", "Hips"), ("LowerLeg", f"UpperLeg_{s}"), ("Foot", f"LowerLeg_{s}"), ("Toes", f"Foot_{s}"))},
}
REQUIRED: tuple[str, ...] = (
    "Hips", "Spine", "Head",
    *(f"{part}_{s}" for s in "LR" for part in ("UpperArm", "LowerArm", "UpperLeg", "LowerLeg", "Foot")),
)
OPTIONAL: tuple[str, ...] = tuple(s for s in SLOTS if s not in REQUIRED)
_SIDED = ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot", "Toes")


class BoneMapError(ValueError):
    """A rig that cannot be mapped, or a bad override: one line.  ``template``: YAML text of an override file listing
    every bone of the rig (a guessed slot, or commented out), where one could be written."""

    def __init__(self, message: str, template: str | None = None):
        super().__init__(message)
        self.template = template
