"""The GNSS model every family shares: measurement preparation, the PPP factor graph, the typed
configuration, robust kernels and mixtures, clustering and the mixture tests. It registers no
estimator and imports no family."""
