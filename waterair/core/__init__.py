"""The bottom layer: parameter validation, device choice and atomic file writes.

Every other sub-package may import from here; this package imports nothing of waterair's.
"""
