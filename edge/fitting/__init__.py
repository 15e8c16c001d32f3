"""Fitting a bundle's records from labelled frames: the per-sensor force calibration (``calibrate``)."""
