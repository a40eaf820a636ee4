//! Integration tests: calibration.
