"""Retrievals and their scores: IGRM, GVMI, SAM, the analysis settings, which designs can be fitted, per-
configuration metrics, the scene's analysis on a simulation.
"""
