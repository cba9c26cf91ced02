"""Pictures of motion (matplotlib, Agg): skeleton figures (:mod:`.skeleton_plot`), GIF/PNG renders of a fill
(:mod:`.render`), the camera and framing (:mod:`.plot_camera`) and the checks of what is drawn (:mod:`.plot_inputs`)."""
