"""The Bone Map sub-panel of the In-between sidebar: the bone map the fill uses for an armature that is not the model's
skeleton (detected, or the rows of the override saved on the armature, ``Armature.inbetween_bone_map``)."""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from inbetweening.runtime import ModelError
from inbetweening.runtime.bone_map import SLOTS, BoneMapError, detect_bone_map

from . import humanoid
from .model import load_model


class InbetweenBoneOverride(bpy.types.PropertyGroup):
    """One row of an armature's bone-map override: ``bone`` plays ``slot`` (``NONE``: no slot)."""

    bone: StringProperty(name="Bone", description="A bone of this armature")
    slot: EnumProperty(name="Slot", description="The model's joint the bone plays",
                       items=[("NONE", "(no slot)", "The bone plays no slot")] + [(s, s, "") for s in SLOTS])


_MAP_CACHE: dict = {}


def bone_map_message(e: BoneMapError) -> str:
    """The runtime's bone-map error with Blender's way to fix it (the Bone Map panel's override, not a file)."""
    text = str(e)
    cut = text.find("; map them in an override file")
    return text if cut < 0 else text[:cut] + "; map them in the Bone Map panel's override (sidebar, In-between tab)"


def detected_map(obj, info):
    """``(BoneMap or None, error line or None)`` of the armature with its saved override (cached by its bones and
    the override)."""
    names, parents, offsets, _ = humanoid.armature_skeleton(obj)
    override = humanoid.stored_override(obj)
    key = (obj.name, tuple(names), tuple(parents), offsets.round(5).tobytes(), tuple(sorted((override or {}).items(),
                                                                                       key=str)))
    if key not in _MAP_CACHE:
        if len(_MAP_CACHE) > 16:
            _MAP_CACHE.clear()
        try:
            _MAP_CACHE[key] = (detect_bone_map(names, parents, offsets, override, where=f"armature '{obj.name}'"), None)
        except BoneMapError as e:
            _MAP_CACHE[key] = (None, bone_map_message(e))
    return _MAP_CACHE[key]


class INBETWEEN_OT_bone_map_add(bpy.types.Operator):
    """Add a row to the active armature's bone-map override (a bone and the model's joint it plays)"""

    bl_idname = "anim.inbetween_bone_map_add"
    bl_label = "Add Bone Map Override"
    bl_options = {"REGISTER", "UNDO"}

    bone: StringProperty(default="")
    slot: StringProperty(default="NONE")

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "ARMATURE"

    def execute(self, context):
        row = context.active_object.data.inbetween_bone_map.add()
        row.bone = self.bone
        if self.slot in SLOTS:
            row.slot = self.slot
        return {"FINISHED"}


class INBETWEEN_OT_bone_map_remove(bpy.types.Operator):
    """Remove a row of the active armature's bone-map override"""

    bl_idname = "anim.inbetween_bone_map_remove"
    bl_label = "Remove Bone Map Override"
    bl_options = {"REGISTER", "UNDO"}

    index: IntProperty(default=-1)

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "ARMATURE"

    def execute(self, context):
        rows = context.active_object.data.inbetween_bone_map
        if 0 <= self.index < len(rows):
            rows.remove(self.index)
        return {"FINISHED"}


class _BoneMapPanel:
    bl_region_type = "UI"
    bl_category = "In-between"
    bl_label = "Bone Map"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "ARMATURE"

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        settings = context.scene.inbetween_settings
        try:
            info = load_model(settings.model_path).info
        except (ModelError, OSError) as e:
            layout.label(text=f"model: {e}"[:80], icon="ERROR")
            return
        if humanoid.is_model_skeleton(obj, info):
            layout.label(text="The model's own skeleton: no map needed", icon="CHECKMARK")
            return
        bm, error = detected_map(obj, info)
        if obj.data.get("rig_id") is not None:
            bm, error = None, humanoid.GENERATED_RIGIFY.format(name=obj.name)
        col = layout.column(align=True)
        if bm is None:
            lines, line = [], ""
            for w in error.split():  # wrapped
                if line and len(line) + len(w) > 42:
                    lines.append(line)
                    line = ""
                line += w + " "
            for i, text in enumerate(lines + [line]):
                col.label(text=text.strip(), icon="ERROR" if i == 0 else "BLANK1")
        else:
            col.label(text=f"{len(bm.slots)} of {len(SLOTS)} slots mapped", icon="ARMATURE_DATA")
            for s in SLOTS:
                row = col.row(align=True)
                row.label(text=s)
                bone = bm.slots.get(s)
                how = bm.how.get(s, "")
                row.label(text=f"{bone}" if bone else "-", icon="BONE_DATA" if bone else "BLANK1")
                row.label(text=how.replace("name ", ""))
        box = layout.box()
        box.label(text="Override (saved with the .blend)")
        rows = obj.data.inbetween_bone_map
        for i, item in enumerate(rows):
            row = box.row(align=True)
            row.prop_search(item, "bone", obj.data, "bones", text="")
            row.prop(item, "slot", text="")
            row.operator(INBETWEEN_OT_bone_map_remove.bl_idname, text="", icon="X").index = i
        box.operator(INBETWEEN_OT_bone_map_add.bl_idname, text="Add Override", icon="ADD")


class INBETWEEN_PT_bone_map_dopesheet(_BoneMapPanel, bpy.types.Panel):
    bl_space_type = "DOPESHEET_EDITOR"
    bl_idname = "INBETWEEN_PT_bone_map_dopesheet"
    bl_parent_id = "INBETWEEN_PT_dopesheet"


class INBETWEEN_PT_bone_map_graph(_BoneMapPanel, bpy.types.Panel):
    bl_space_type = "GRAPH_EDITOR"
    bl_idname = "INBETWEEN_PT_bone_map_graph"
    bl_parent_id = "INBETWEEN_PT_graph"


class INBETWEEN_PT_bone_map_view3d(_BoneMapPanel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_idname = "INBETWEEN_PT_bone_map_view3d"
    bl_parent_id = "INBETWEEN_PT_view3d"


