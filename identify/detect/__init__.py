"""Change detection on model residuals (seed 000 chapter 5): the dead-zone CUSUM of (5.1) and a
likelihood-ratio CUSUM along the signature of each candidate change, which also names the change."""
