//! wgpu device bring-up and GPU passes. Every pass has a CPU reference in `crate::light`.
