"""Tightly coupled GNSS/INS: strapdown mechanisation, the EKF/IEKF and CRT-LSS window solver, and
the data they share."""
