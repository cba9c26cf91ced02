"""The rig kinds: a rig of the model's own skeleton fills directly (:class:`~.host.Rig`); any other humanoid through
the bone map and retargeting (:class:`MappedRig`), whatever host it lives in.

A :class:`MappedRig` is the rig's skeleton in the BVH convention (names, parents first, rest offsets head to head;
every rest rotation the identity), its bones mapped to the model's slots (:func:`inbetweening.runtime.bone_map.
detect_bone_map`, with the animator's override on top) and its motion carried to the model's skeleton and back
(:class:`~inbetweening.runtime.retarget.Retarget`, :meth:`FillRuntime.fill_rig
<inbetweening.runtime.fill.FillRuntime.fill_rig>`).  The fill keys the rotation of every bone with a slot or between
slots in a chain, and the location of the bone that carries the hips (:meth:`MappedRig.plan`); bones without a slot
(fingers, face, twist leaves, props) keep their curves.

A host whose bone channels are relative to the bone's rest frame (Blender's ``matrix_basis``; Maya's rotate and
translate under its joint orient) reads and writes them through :meth:`MappedRig.to_local` and
:meth:`MappedRig.to_basis`: with ``R`` a bone's rest rotation in the rig's space and ``B`` its channels, the local
rotation is ``R rot(B) R^-1`` and the local translation ``offset + R loc(B)``.
"""
from __future__ import annotations

import numpy as np

from inbetweening.geometry.quaternion import qinv, qmul, qnormalize, qrot
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.runtime.bone_map import SLOTS, detect_bone_map
from inbetweening.runtime.retarget import Retarget, rig_plan

from .host import Rig

__all__ = ["MappedRig", "is_model_skeleton"]


def is_model_skeleton(bones, model) -> bool:
    """Whether a rig with the bones named ``bones`` is filled as the model's own skeleton (:class:`~.host.Rig`): it
    has every joint of the model (``model``: its :class:`~inbetweening.runtime.model.ModelInfo`) by name and the
    model's joints are not the humanoid slots.  A model of the slots fills every rig, its own skeleton too, through
    :class:`MappedRig` (the identity case of the retargeting)."""
    names = set(bones)
    return set(model.skeleton.names) != set(SLOTS) and all(n in names for n in model.skeleton.names)


class MappedRig(Rig):
    """A humanoid rig that is not the model's skeleton (module docstring).  ``names``, ``parents``, ``offsets``: its
    skeleton in the BVH convention; ``override``: ``{bone: slot or None}`` on top of the detected bone map (a
    :class:`~inbetweening.runtime.bone_map.BoneMapError` names what cannot be mapped); ``rest``: the bones' rest
    rotations ``(J, 4)`` in the rig's space (:meth:`to_local`; default the identity).

    A front end implements :meth:`key_channels`, :meth:`read`, :meth:`channels` and :meth:`basis_values` (its pose
    channels), and where it knows them :meth:`is_bone`, :meth:`connected`, :meth:`has_location` and :meth:`ends`."""

    retargeted = True

    def __init__(self, curves, model, where: str, names, parents, offsets, override: dict | None = None,
                 rest: np.ndarray | None = None):
        self.curves, self.model, self.where = curves, model, where
        self.names, self.parents, self.offsets = names, parents, offsets
        self.skeleton = Skeleton(names, parents, offsets)
        self.map = detect_bone_map(names, parents, offsets, override, where=where)
        self.r = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1)) if rest is None else np.asarray(rest, np.float64)
        self._retarget: Retarget | None = None
        self._retarget_inputs: tuple | None = None
        self.rot_bones: list[int] = []
        self.movers: list[int] = []

    @property
    def joint_names(self) -> list[str]:
        return list(self.names)

    # ------------------------------------------------------------------ what the host knows of its bones
    def is_bone(self, j: int) -> bool:
        """Whether joint ``j`` is a bone of the host (not a joint added above several root bones)."""
        return True

    def connected(self, j: int) -> bool:
        """Whether bone ``j``'s head sits on its parent's tail, so that its location is not its own."""
        return False

    def has_location(self, j: int) -> bool:
        """Whether bone ``j``'s location is animated (a curve on one of its location channels)."""
        return False

    def ends(self) -> dict[int, np.ndarray] | None:
        """Per leaf bone, its head to its tail in the rig's space (a BVH end site), where the host knows it."""
        return None

    # ------------------------------------------------------------------ the mapping
    def retarget_at(self, reference: np.ndarray, poses=None, translations=None, ends=None) -> None:
        """Set the pose the :class:`Retarget` from the rig to the model (:attr:`retarget`) is built from
        (``reference``: the rig's local rotations at the first key; ``poses``, ``translations``: its local rotations
        and translations at every key, where its up, natural pose and floor are read).  It is built when the fill first
        needs it: a re-fill with nothing changed never does."""
        self._retarget, self._retarget_inputs = None, (reference, poses, translations, ends)

    @property
    def retarget(self) -> Retarget:
        """The :class:`Retarget` from the rig to the model at the pose :meth:`retarget_at` set (built on first use)."""
        if self._retarget is None:
            if self._retarget_inputs is None:
                raise RuntimeError(f"{self.where}: plan() before the retargeting")
            reference, poses, translations, ends = self._retarget_inputs
            self._retarget = Retarget(self.skeleton, self.model.skeleton, self.map, reference=reference, poses=poses,
                                      translations=translations, ends=ends)
        return self._retarget

    def plan(self, reference: np.ndarray, poses=None, translations=None) -> None:
        """:meth:`retarget_at` (with :meth:`ends`), and the bones the fill writes (from the skeletons and the map alone,
        :func:`~inbetweening.runtime.retarget.rig_plan`): the rotation of every bone with a slot or between slots in a
        chain, and ``movers``: the bone that carries the hips' translation (the nearest unconnected bone at or above
        the hips with an animated location, else the hips when unconnected)."""
        self.retarget_at(reference, poses, translations, self.ends())
        self.rot_bones = [j for j, p in enumerate(rig_plan(self.skeleton, self.model.skeleton, self.map))
                          if p[0] != "free" and self.is_bone(j)]
        hips = self.names.index(self.map.slots["Hips"])
        chain = [hips]
        while self.parents[chain[-1]] >= 0:
            chain.append(self.parents[chain[-1]])
        free = [j for j in chain if self.is_bone(j) and not self.connected(j)]
        keyed = [j for j in free if self.has_location(j)]
        self.movers = keyed[:1] or ([hips] if hips in free else [])

    def fill(self, runtime, a: np.ndarray, b: np.ndarray, keys: list[int], **kw):
        """:meth:`FillRuntime.fill_rig <inbetweening.runtime.fill.FillRuntime.fill_rig>` of the rig's ``local_q``
        ``a`` and ``local_p`` ``b``."""
        out = runtime.fill_rig(self.retarget, a, b, keys, movers=self.movers, **kw)
        return out.model, out.local_q, out.local_p, out.generated

    # ------------------------------------------------------------------ channels in the bone's rest frame
    def to_local(self, qb: np.ndarray, loc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``local_q (F, J, 4)``, ``local_p (F, J, 3)`` in the BVH convention of the bones' channel rotations ``qb (F,
        J, 4)`` and locations ``loc (F, J, 3)`` in their rest frames (module docstring)."""
        r = self.r[None]
        lq = qnormalize(qmul(qmul(r, qb), qinv(r)), 0.0)
        lp = self.offsets[None] + qrot(np.broadcast_to(r, loc.shape[:-1] + (4,)), loc)
        return lq, lp

    def to_basis(self, local_q: np.ndarray, local_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`to_local`'s inverse: the channel rotations ``qb`` and locations ``loc`` of a pose."""
        r = self.r[None]
        qb = qmul(qmul(qinv(r), local_q), r)
        loc = qrot(np.broadcast_to(qinv(r), local_p.shape[:-1] + (4,)), local_p - self.offsets[None])
        return qb, loc

    def summary(self) -> dict:
        return {"bone_map": dict(self.map.slots), "how": dict(self.map.how), "movers": [self.names[j] for j in self.movers],
                "keyed_bones": self.keyed_bones(), "rig_root": self.names[0], "rigify": False}

    def keyed_bones(self) -> list[str]:
        """The bones whose rotation the fill writes."""
        return [self.names[j] for j in self.rot_bones]
