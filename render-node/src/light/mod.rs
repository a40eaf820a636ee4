//! Pure light transport: no IO, no GPU. Ray casting, device projection,
//! visibility and the CPU reference renderers that every GPU pass is
//! checked against.
#![forbid(unsafe_code)]

pub mod raster;
