"""A pruned, temporary copy of an armature that Blender evaluates in its place (:class:`RigProxy`): only the bones some
reads depend on, so one evaluation of a big rig costs a fraction (a rig Rigify generates, 706 bones: 4.0-5.5 ms per
evaluation; its copy for the FK-control solve, 130 bones: 2.3-2.6 ms; BENCHMARKS.md, "Blender extension").

- **Which bones** (:func:`needed_bones`): the bones read, their parents, their constraints' targets, the bones their
  drivers read (a bone target or a ``pose.bones["X"]`` in a property path), and so on up: everything that poses them,
  so the proxy poses them exactly as the armature does.
- **Its channels**: the armature's pose at the moment the proxy is made; the animated channels of its bones and the
  object's own custom properties (the armature's action, but for ``skip``: the channels the caller sets itself) are
  set at each frame by :meth:`RigProxy.set_frame`, and only the proxy is evaluated (``view_layer.update()``), never
  the scene's frame.
- **Nothing left behind**: the copy and its armature data are removed when the ``with`` block ends, also on an error;
  the armature's mode (pruning the copy needs edit mode, which needs the armature out of its mode for the moment) and
  the active object are restored as soon as the copy is made.
"""
from __future__ import annotations

import re

import bpy

from .curves import channelbag

_BONE = re.compile(r'pose\.bones\["((?:[^"\\]|\\.)*)"\]')
_DATA_BONE = re.compile(r'bones\["((?:[^"\\]|\\.)*)"\]')  # a path on the armature data (B-bone ease, ...)


def _drivers(obj) -> dict:
    """``{bone name: [driver]}``: the object's drivers of its pose bones and the armature's of its bones."""
    out: dict = {}
    for owner, pattern in ((obj.animation_data, _BONE), (obj.data.animation_data, _DATA_BONE)):
        for d in (owner.drivers if owner is not None else ()):
            m = pattern.match(d.data_path)
            if m:
                out.setdefault(m.group(1), []).append(d)
    return out


def needed_bones(obj, start) -> set[str]:
    """The pose bones of ``obj`` whose evaluation poses the bones ``start``: those, their parents, their constraints'
    targets (in ``obj``) and the bones their drivers (the object's and the armature's) read, and so on up."""
    pose, drivers = obj.pose.bones, _drivers(obj)
    need: set = set()
    stack = list(start)
    while stack:
        name = stack.pop()
        if not name or name in need or name not in pose:
            continue
        need.add(name)
        pb = pose[name]
        stack += [pb.parent.name] if pb.parent is not None else []
        for c in pb.constraints:
            if getattr(c, "target", None) in (None, obj):
                stack += [getattr(c, "subtarget", "") or "", getattr(c, "pole_subtarget", "") or ""]
            stack += [t.subtarget for t in getattr(c, "targets", ()) if getattr(t, "target", None) == obj]
        for d in drivers.get(name, ()):
            for v in d.driver.variables:
                for t in v.targets:
                    if t.id == obj or t.id == obj.data:
                        stack += [t.bone_target] + _DATA_BONE.findall(t.data_path or "")  # also in pose.bones["X"]
    return need


def set_channel(owner, path: str, index: int, value: float) -> None:
    """Set channel ``(path, index)`` of ``owner`` (an RNA property, an array's element or a custom property)."""
    if path.endswith('"]'):  # a custom property: owner["name"]
        head, key = path[: path.rindex('["')], path[path.rindex('["') + 2: -2]
        holder = owner.path_resolve(head) if head else owner
        cur = holder[key]
        if hasattr(cur, "__len__"):
            cur[index] = value
        else:
            holder[key] = type(cur)(value) if isinstance(cur, (int, float)) else value
        return
    head, attr = path.rsplit(".", 1)
    holder = owner.path_resolve(head)
    cur = getattr(holder, attr)
    if hasattr(cur, "__len__") and not isinstance(cur, str):
        cur[index] = value
    else:
        setattr(holder, attr, type(cur)(value))


class RigProxy:
    """``with RigProxy(obj, reads, skip) as px``: ``px.bone(name)``: the proxy's pose bone of that name (every bone in
    ``reads`` is there); ``px.obj``: the proxy object; ``px.set_frame(frame)``: its animated channels (but ``skip``'s
    ``(data_path, index)``) at ``frame``, then one evaluation; ``px.update()``: one evaluation."""

    def __init__(self, obj, reads, skip=()):
        self.source, self.keep = obj, needed_bones(obj, reads)
        skip = set(skip)
        bag = channelbag(obj)
        self.curves = [fc for fc in (bag.fcurves if bag is not None else ())  # its bones' and its own custom ones
                       if (fc.data_path, fc.array_index) not in skip and not fc.mute
                       and ((m := _BONE.match(fc.data_path)) and m.group(1) in self.keep or fc.data_path.startswith('["'))]
        self.obj = None

    def __enter__(self) -> RigProxy:
        src = self.source
        mode, active = src.mode, bpy.context.view_layer.objects.active
        try:
            if mode != "OBJECT":  # pruning the copy needs edit mode, which needs every other armature out of its mode
                with bpy.context.temp_override(active_object=src, object=src):
                    bpy.ops.object.mode_set(mode="OBJECT")
            self.obj = obj = src.copy()
            obj.data = src.data.copy()
            obj.name = obj.data.name = f"{src.name} (fill solve)"
            bpy.context.scene.collection.objects.link(obj)
            if obj.animation_data is not None:
                obj.animation_data.action = None
            for owner, pattern in ((obj.animation_data, _BONE), (obj.data.animation_data, _DATA_BONE)):
                for d in [d for d in (owner.drivers if owner is not None else ())  # the drivers of the bones gone
                          if (m := pattern.match(d.data_path)) and m.group(1) not in self.keep]:
                    owner.drivers.remove(d)
            with bpy.context.temp_override(active_object=obj, object=obj, selected_objects=[obj],
                                           selected_editable_objects=[obj]):
                bpy.ops.object.mode_set(mode="EDIT")
                edit = obj.data.edit_bones
                for b in [b for b in edit if b.name not in self.keep]:
                    edit.remove(b)
                bpy.ops.object.mode_set(mode="OBJECT")
            self.update()
        except BaseException:
            self._remove()
            raise
        finally:
            if mode != "OBJECT":
                with bpy.context.temp_override(active_object=src, object=src):
                    bpy.ops.object.mode_set(mode=mode)
            bpy.context.view_layer.objects.active = active
        return self

    def __exit__(self, *exc) -> None:
        self._remove()

    def _remove(self) -> None:
        if self.obj is not None:
            data = self.obj.data
            bpy.data.objects.remove(self.obj)
            bpy.data.armatures.remove(data)
            self.obj = None

    def bone(self, name: str):
        return self.obj.pose.bones[name]

    def update(self) -> None:
        bpy.context.view_layer.update()

    def set_frame(self, frame: float) -> None:
        for fc in self.curves:
            set_channel(self.obj, fc.data_path, fc.array_index, fc.evaluate(frame))
        self.update()
