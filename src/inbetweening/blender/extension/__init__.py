"""In-betweening for Blender: fill the frames between an armature's keys with a trained in-betweening model.

The model runs with ONNX Runtime (bundled as wheels); no PyTorch.  See README.md next to this file.
"""


def register():
    from . import operators

    operators.register()


def unregister():
    from . import operators

    operators.unregister()
