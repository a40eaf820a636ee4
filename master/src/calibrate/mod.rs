//! Device calibration from fiducials (paper section 3.1): DLT, RQ, PnP, Levenberg-Marquardt, and Powell as the baseline.
