"""Geometry: quaternions (wxyz), skeletons, forward/inverse kinematics; numpy and torch alike."""
