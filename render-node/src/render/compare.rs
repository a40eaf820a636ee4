//! GPU-versus-CPU comparison of projector maps: relative RMSE of `L` over
//! all surface pixels and away from edges, and where the outliers are.

use super::projector_gpu::GpuIrradianceMap;
use crate::gpu::irradiance_map::state;
use glam::Vec3;
use showcase_light::metrics::relative_rmse;
use showcase_light::render::projector::{IrradianceMap, PixelState, edge_mask};
use showcase_light::{Image, MetricError, RgbImage};

/// A pixel differs "a lot" when its relative difference exceeds this.
pub const OUTLIER_RELATIVE: f64 = 0.01;

/// Pixels within this many pixels of a silhouette or shadow edge of the
/// CPU reference are "edge" pixels: a shadow map texel and a ray may
/// disagree there.
pub const EDGE_RADIUS_PX: u32 = 2;

/// How a GPU map compares with its CPU reference.
#[derive(Clone, Debug, PartialEq)]
pub struct MapComparison {
    /// Relative RMSE of `L` over the surface pixels the reference shows
    /// unclipped.
    pub rel_rmse: f64,
    /// The same, leaving out edge pixels.
    pub rel_rmse_off_edges: f64,
    /// Pixels compared.
    pub pixels: usize,
    /// Outlier pixels (relative difference above [`OUTLIER_RELATIVE`]).
    pub outliers: usize,
    /// Outliers that are not edge pixels.
    pub outliers_off_edges: usize,
    /// Surface pixels whose state code differs (masked / clipped).
    pub state_mismatches: usize,
}

/// The GPU map's `L` as an image.
pub fn gpu_irradiance(gpu: &GpuIrradianceMap) -> RgbImage {
    Image {
        width: gpu.width,
        height: gpu.height,
        data: gpu
            .irradiance
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect(),
    }
}

/// The GPU map with the CPU reference's per-pixel state (surface, lit
/// samples, occlusion) and the GPU's own clipped flags and values: what
/// the consistency check of GPU output needs.
pub fn gpu_map_with_reference_state(gpu: &GpuIrradianceMap, cpu: &IrradianceMap) -> IrradianceMap {
    let state = Image {
        width: cpu.state.width,
        height: cpu.state.height,
        data: cpu
            .state
            .data
            .iter()
            .zip(&gpu.irradiance)
            .map(|(s, g)| PixelState {
                clipped: g[3] == state::CLIPPED,
                masked: s.masked || g[3] == state::MASKED || g[3] == state::BACKGROUND,
                ..*s
            })
            .collect(),
    };
    IrradianceMap {
        irradiance: gpu_irradiance(gpu),
        value: Image {
            width: gpu.width,
            height: gpu.height,
            data: gpu
                .value
                .iter()
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
        },
        state,
        clipped_fraction: gpu.clipped_fraction,
    }
}

/// Compare `gpu` with `cpu`.
pub fn compare_maps(
    gpu: &GpuIrradianceMap,
    cpu: &IrradianceMap,
) -> Result<MapComparison, MetricError> {
    let n = cpu.state.data.len();
    if gpu.irradiance.len() != n || cpu.irradiance.data.len() != n {
        return Err(MetricError::SizeMismatch {
            test: gpu.irradiance.len(),
            reference: cpu.irradiance.data.len(),
            mask: n,
        });
    }
    let g = gpu_irradiance(gpu);
    let edges = edge_mask(&cpu.state, EDGE_RADIUS_PX, false);
    // Pixels the reference shows unclipped: a clipped pixel shows the
    // device limit whatever its `L` (clipping agreement is counted in
    // `state_mismatches`).
    let surface = |i: usize| {
        let s = &cpu.state.data[i];
        !s.masked && !s.clipped
    };
    let all = Image {
        width: cpu.state.width,
        height: cpu.state.height,
        data: (0..n).map(surface).collect::<Vec<bool>>(),
    };
    let off = all.map(|&b| b);
    let off = Image {
        data: off
            .data
            .iter()
            .zip(&edges.data)
            .map(|(a, e)| *a && !e)
            .collect(),
        ..off
    };
    let rel_rmse = relative_rmse(&g, &cpu.irradiance, Some(&all))?;
    let rel_rmse_off_edges = relative_rmse(&g, &cpu.irradiance, Some(&off))?;
    let mean = {
        let (s, c) = (0..n)
            .filter(|&i| all.data[i])
            .fold((0.0, 0usize), |(s, c), i| {
                (
                    s + cpu.irradiance.data[i].as_dvec3().element_sum() / 3.0,
                    c + 1,
                )
            });
        if c == 0 { 0.0 } else { s / c as f64 }
    };
    let (mut outliers, mut outliers_off_edges, mut state_mismatches) = (0, 0, 0);
    for i in 0..n {
        let gs = gpu.irradiance[i][3];
        let cs = &cpu.state.data[i];
        let gpu_masked = gs == state::MASKED || gs == state::BACKGROUND;
        let differs =
            cs.masked != gpu_masked || (!cs.masked && cs.clipped != (gs == state::CLIPPED));
        if differs && !edges.data[i] {
            state_mismatches += 1;
        }
        if !all.data[i] {
            continue;
        }
        let d = (g.data[i] - cpu.irradiance.data[i])
            .as_dvec3()
            .abs()
            .max_element();
        let scale = cpu.irradiance.data[i].as_dvec3().max_element().max(mean);
        if d > OUTLIER_RELATIVE * scale {
            outliers += 1;
            if !edges.data[i] {
                outliers_off_edges += 1;
            }
        }
    }
    Ok(MapComparison {
        rel_rmse,
        rel_rmse_off_edges,
        pixels: all.data.iter().filter(|b| **b).count(),
        outliers,
        outliers_off_edges,
        state_mismatches,
    })
}
