//! Reflectance maps (paper section 3.4): pure math.
