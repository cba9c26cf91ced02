"""The command lines: ``python -m inbetweening.predict`` (:mod:`.predict`), ``python -m inbetweening.export``
(:mod:`.export`) and their shared argument parsing (:mod:`.args`)."""
