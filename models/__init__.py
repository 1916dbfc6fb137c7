"""Internal (not a stable API; use driftfmu.simulate instead).

The math of driftfmu, written once (Chorti et al., Sensor Letters 4(4):377-379, 2006).

Plain arithmetic on Python floats (inside an FMU, standard library only) and on NumPy arrays (a
batch of Monte-Carlo runs) alike, with the same bits on both paths.  Modules: ``noise``
(counter-based Gaussian noise), ``excitation``, ``sensor``, ``ekf``, ``drift`` (EKF1-3 and the
references), ``chain`` (the whole measurement chain), ``harmonic`` (2-state process model),
``adxl203`` (the accelerometer stand-in), ``errors`` (the sensor's slow errors: the letter's
drift classes 2 to 4 and the range), ``dualaxis`` (the dual-axis sensor with a bilinear
cross term and its joint EKF), ``identify`` and ``parameters``.
"""
