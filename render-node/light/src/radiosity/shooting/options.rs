//! Settings of a progressive-refinement solve: the form-factor method,
//! who makes the hemi-cube's item buffers, and why a solve cannot start.

use crate::radiosity::hemicube::{ItemBufferError, ItemBufferRasteriser};
use crate::radiosity::shooting::ConvergencePoint;
use std::sync::Arc;

/// How a shot's form factors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FormFactorMethod {
    /// Hemi-cube at the shooter's centre for every receiver.
    HemiCube,
    /// Ray-cast form factors for every receiver (Wallace-style): the
    /// closed-form point-to-polygon form factor to the whole shooting patch,
    /// averaged over `n^2` sub-triangle centroids of the receiver (`n` from
    /// 1 to 8, growing as the pair gets close relative to its size), times
    /// the visible fraction of `visibility_samples` rays between paired
    /// jittered points of the receiver and the patch.
    RayCast,
    /// The hemi-cube, except for receivers where it is known to fail: close
    /// to the shooter (distance below `proximity * sqrt(A_shooter)`, where
    /// the shooter is not a point) and small receivers (expected to cover
    /// fewer than `min_pixels` hemi-cube pixels, where it aliases); those
    /// are ray-cast.
    Hybrid,
}

/// Who makes the hemi-cube's item buffers (where [`FormFactorMethod`]
/// uses the hemi-cube: `HemiCube` and `Hybrid`).
#[derive(Clone, Default)]
pub enum ItemBufferBackend {
    /// One ray per pixel centre into the shared BVH, on the CPU.
    #[default]
    Cpu,
    /// A rasteriser, e.g. `showcase_render::gpu::hemicube::GpuHemiCube`.
    Raster(Arc<dyn ItemBufferRasteriser>),
}

impl std::fmt::Debug for ItemBufferBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Cpu => f.write_str("Cpu"),
            Self::Raster(r) => write!(f, "Raster({})", r.describe()),
        }
    }
}

impl PartialEq for ItemBufferBackend {
    /// Equal when both are the CPU or both the same rasteriser object.
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Cpu, Self::Cpu) => true,
            (Self::Raster(a), Self::Raster(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

/// Why a solve cannot start.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SolveError {
    /// The hemi-cube resolution is invalid.
    #[error(transparent)]
    HemiCube(#[from] crate::radiosity::hemicube::HemiCubeError),
    /// The threshold is not in `(0, 1)`.
    #[error("unshot-energy threshold {0} must be in (0, 1)")]
    BadThreshold(f64),
    /// The item-buffer rasteriser could not take the mesh.
    #[error(transparent)]
    ItemBuffer(#[from] ItemBufferError),
    /// The active mask does not have one entry per element.
    #[error("active mask has {got} entries for {elements} elements")]
    MaskLength {
        /// Entries given.
        got: usize,
        /// Elements in the mesh.
        elements: usize,
    },
}

/// Settings of a progressive-refinement solve.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveOptions {
    /// Hemi-cube top-face resolution (even).
    pub hemicube: u32,
    /// Stop when unshot power / injected power falls below this.
    pub threshold: f64,
    /// Form-factor method.
    pub method: FormFactorMethod,
    /// Hard limit on shots.
    pub max_shots: usize,
    /// Seed of the per-shot hemi-cube rotation and sample jitter.
    pub seed: u64,
    /// Hybrid: receivers closer than `proximity * sqrt(A_shooter)` are ray-cast.
    pub proximity: f64,
    /// Hybrid: receivers expected to cover fewer pixels are ray-cast.
    pub min_pixels: f64,
    /// Visibility rays per ray-cast form factor (and per area light).
    pub visibility_samples: u32,
    /// Memory for cached form-factor rows (bytes); 0 disables the cache.
    pub form_factor_cache_bytes: usize,
    /// Who makes the hemi-cube item buffers.
    pub item_buffer: ItemBufferBackend,
    /// Told after every shot (progress display; none by default).
    pub progress: ShotProgress,
}

/// A callback told the shots so far and the unshot fraction after every
/// shot of a solve, so that a caller can show progress: the solver itself
/// does no IO. Each solve (refinement round, augmented pass) counts its
/// shots from 1.
#[derive(Clone, Default)]
pub struct ShotProgress(Option<Arc<dyn Fn(ConvergencePoint) + Send + Sync>>);

impl ShotProgress {
    /// Call `f` after every shot.
    pub fn new(f: impl Fn(ConvergencePoint) + Send + Sync + 'static) -> Self {
        Self(Some(Arc::new(f)))
    }

    /// Tell the callback, if there is one.
    pub(crate) fn report(&self, point: ConvergencePoint) {
        if let Some(f) = &self.0 {
            f(point);
        }
    }
}

impl std::fmt::Debug for ShotProgress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "ShotProgress(set)"
        } else {
            "ShotProgress(none)"
        })
    }
}

impl PartialEq for ShotProgress {
    /// Equal when neither is set or both are the same callback.
    fn eq(&self, other: &Self) -> bool {
        match (&self.0, &other.0) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            hemicube: 64,
            threshold: 1e-3,
            method: FormFactorMethod::Hybrid,
            max_shots: 1_000_000,
            seed: 1,
            proximity: 2.0,
            min_pixels: 4.0,
            visibility_samples: 4,
            form_factor_cache_bytes: 1 << 30,
            item_buffer: ItemBufferBackend::Cpu,
            progress: ShotProgress::default(),
        }
    }
}
