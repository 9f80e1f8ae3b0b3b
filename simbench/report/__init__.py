"""Report building: figures and pages from the results store (no numerics here beyond plotting)."""
