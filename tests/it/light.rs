//! Integration tests: light.
