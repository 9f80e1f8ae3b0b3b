"""Recursive filters on the PPP model: the extended Kalman filter (:mod:`.ekf_ppp`)."""
