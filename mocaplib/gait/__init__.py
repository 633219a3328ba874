"""Gait analysis of a fitted motion: events, cycles cut at left toe-off, the path pattern and
velocities of each cycle, Fourier encoding, poulaines, biomechanical criteria and quality control."""
