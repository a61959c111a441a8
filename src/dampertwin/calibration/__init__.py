"""Calibration: GA fits (pygad) of the thesis approaches."""
