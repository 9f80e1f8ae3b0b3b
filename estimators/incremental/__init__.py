"""Incremental estimators on iSAM2 with a fixed-lag window: iSAM2-PPP, -DCS and -MM (:mod:`.isam2`)
and ICE (:mod:`.ice`)."""
