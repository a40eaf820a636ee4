//! Integration tests: radiosity.
