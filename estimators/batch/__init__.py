"""Batch factor-graph estimators: L2, DCS and max-mixtures (:mod:`.robust`), BCE and BCE-AD
(:mod:`.bce`), the label-reading oracle (:mod:`.oracle`), and the sparse Gauss-Newton solver they
share."""
