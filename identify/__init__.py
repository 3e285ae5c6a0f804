"""Identify a ship from its recordings: the seed systems beside the mismatch diagnosis.

- :mod:`identify.yawid`: yaw dynamics of a podded ship from manoeuvring data (the podded-ship MSc thesis, ch. 2-3).
- :mod:`identify.detect`: change detection on that ship, dead-zone and likelihood-ratio CUSUM (ibid., ch. 4-5).
- :mod:`identify.rollmass`: mass and height of the centre of gravity from roll (Linder et al. 2015).

Recordings are read by :mod:`diagnose.recording` (the project's one CSV/MARIN reader); this package never
imports :mod:`cli`.
"""
