"""The retargeting task (``task=retarget``): a network that carries a motion of the source skeleton (the model's, e.g.
Bandai-Namco-2's) onto a target rig of another topology, trained on the analytic retarget.  One package beside the
in-betweening task, on the same shared layers (data, geometry, models, runtime's analytic :class:`~inbetweening.
runtime.retarget.Retarget`, training's builders and schedules):

- :mod:`.rig`: the target rig, its analytic retarget and the features both ways (numpy);
- :mod:`.data`: source clips paired with their analytic retarget, the split, statistics, windows;
- :mod:`.module`: the LightningModule and its losses;
- :mod:`.learned`: a trained checkpoint applied to a motion (run time);
- :mod:`.metrics`: the scores of a retargeted motion; :mod:`.evaluate`: scoring held-out clips, the table;
- :mod:`.figure`: the side-by-side figure;
- :mod:`.task`: the jobs behind ``train.py task=retarget`` and ``eval.py task=retarget``;
- :mod:`.cli`: ``python -m inbetweening.retarget`` (a BVH of the source onto the target rig).
"""
