"""In-betweening for Blender: fill the frames between an armature's keys with a trained in-betweening model.

The model runs with ONNX Runtime (bundled as wheels); no PyTorch.  See README.md next to this file.
"""


def register():
    from . import loop, operators

    operators.register()
    loop.register()


def unregister():
    from . import loop, operators

    loop.unregister()
    operators.unregister()
