"""Feature representations: the one owner of the feature layout (see :mod:`.base`).

A new representation is one module holding one :class:`~.base.Representation` subclass and one line in
:data:`REPRESENTATIONS`; it is chosen by name (``representation=<name>``) and restored from a checkpoint's
hyper-parameters by :func:`build_representation`.
"""
from __future__ import annotations

from inbetweening.geometry.skeleton import Skeleton

from .base import Representation
from .global_pos_local_quat import GlobalPosLocalQuat
from .global_pos_local_quat_contact import GlobalPosLocalQuatContact

REPRESENTATIONS: dict[str, type[Representation]] = {
    GlobalPosLocalQuat.name: GlobalPosLocalQuat,
    GlobalPosLocalQuatContact.name: GlobalPosLocalQuatContact,
}
DEFAULT_REPRESENTATION = GlobalPosLocalQuat.name  # what every checkpoint made before the option used


def representation_class(name: str) -> type[Representation]:
    """``REPRESENTATIONS[name]``; ValueError naming ``representation`` if unknown."""
    if name not in REPRESENTATIONS:
        raise ValueError(f"representation: unknown representation {name!r}; choose one of {sorted(REPRESENTATIONS)}")
    return REPRESENTATIONS[name]


def build_representation(name: str, skeleton: Skeleton, mean, std, **kw) -> Representation:
    """``REPRESENTATIONS[name](skeleton, mean, std, **kw)`` (``contact``, ``fps``: the data's contact rule and frame
    rate); ValueError naming ``representation`` if unknown."""
    return representation_class(name)(skeleton, mean, std, **kw)


__all__ = ["DEFAULT_REPRESENTATION", "REPRESENTATIONS", "GlobalPosLocalQuat", "GlobalPosLocalQuatContact", "Representation",
           "build_representation",
           "representation_class"]
