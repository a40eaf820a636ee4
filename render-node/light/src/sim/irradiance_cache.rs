//! Irradiance caching (Ward, Rubinstein and Clear 1988) of the simulated
//! world's indirect light, for low-noise ground-truth images.
//!
//! Indirect irradiance varies slowly over a surface, so many paths at a few
//! points, interpolated, are far less noisy than a few paths at every
//! pixel. Each cache point holds the indirect irradiance
//! ([`SimWorld::indirect_irradiance`], as two independent halves of its
//! paths) and a validity radius `R`: the harmonic mean of its paths' first
//! hit distances, clamped to `[min_radius, max_radius]`. A query point `p`
//! with normal `n` uses cache point `i` (same object, not behind it) when
//! Ward's error `|p - p_i| / R_i + sqrt(1 - n . n_i)` is below
//! `accuracy`, weighted by its inverse. Where no cache point is valid the
//! caller computes the point itself ([`IrradianceCache::lookup`] says
//! `None`).
//!
//! Deterministic: the cache is built from a given list of points in one
//! parallel pass (no order-dependent insertion), each point on the random
//! streams of its own key.

use super::{SimLights, SimWorld, SurfacePoint};
use crate::sampling::pixel_seed;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// How the cache is built and read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CacheOptions {
    /// Paths per cache point, both halves together (at least 2).
    pub paths: u32,
    /// Ward's `a`: the largest error a cache point may be used at.
    pub accuracy: f64,
    /// Smallest validity radius (metres).
    pub min_radius: f64,
    /// Largest validity radius (metres).
    pub max_radius: f64,
}

/// One cache point.
#[derive(Clone, Debug)]
struct CachePoint {
    point: DVec3,
    normal: DVec3,
    object: u32,
    radius: f64,
    /// Indirect irradiance from two disjoint halves of the paths.
    halves: [DVec3; 2],
}

/// The cache (see the module docs).
#[derive(Clone, Debug)]
pub struct IrradianceCache {
    points: Vec<CachePoint>,
    /// Cache points by grid cell of side `cell`.
    grid: HashMap<[i64; 3], Vec<u32>>,
    cell: f64,
    accuracy: f64,
}

impl IrradianceCache {
    /// Cache points at `seeds` (each a surface point and the key of its
    /// random streams), in `world` under `lights`.
    pub fn build(
        world: &SimWorld,
        lights: &SimLights<'_>,
        seeds: &[(SurfacePoint, u64)],
        options: CacheOptions,
    ) -> Self {
        let half = (options.paths / 2).max(1);
        let (lo, hi) = (
            options.min_radius,
            options.max_radius.max(options.min_radius),
        );
        let points: Vec<CachePoint> = seeds
            .par_iter()
            .map(|(s, key)| {
                let (a, ra) = world.indirect_irradiance(s, lights, half, pixel_seed(*key, 0));
                let (b, rb) = world.indirect_irradiance(s, lights, half, pixel_seed(*key, 1));
                // Harmonic mean of both halves' harmonic means.
                let inverse = 1.0 / ra + 1.0 / rb;
                let radius = if inverse > 0.0 { 2.0 / inverse } else { hi };
                CachePoint {
                    point: s.point,
                    normal: s.facing,
                    object: s.object,
                    radius: radius.clamp(lo, hi),
                    halves: [a, b],
                }
            })
            .collect();
        let cell = (hi * options.accuracy).max(1e-9);
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            grid.entry(cell_of(p.point, cell))
                .or_default()
                .push(i as u32);
        }
        Self {
            points,
            grid,
            cell,
            accuracy: options.accuracy,
        }
    }

    /// The interpolated indirect irradiance at `surface`, as two halves;
    /// `None` where no cache point is valid.
    pub fn lookup(&self, surface: &SurfacePoint) -> Option<[DVec3; 2]> {
        let c = cell_of(surface.point, self.cell);
        let (mut sum, mut weight) = ([DVec3::ZERO; 2], 0.0);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = self.grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &i in list {
                        let p = &self.points[i as usize];
                        if p.object != surface.object {
                            continue;
                        }
                        let d = surface.point - p.point;
                        // Not in front of the cache point's surface.
                        if d.dot(p.normal) < -0.05 * p.radius {
                            continue;
                        }
                        let bend = (1.0 - surface.facing.dot(p.normal)).max(0.0).sqrt();
                        let error = d.length() / p.radius + bend;
                        if !(error < self.accuracy) {
                            continue;
                        }
                        let w = 1.0 / error.max(1e-6);
                        sum[0] += w * p.halves[0];
                        sum[1] += w * p.halves[1];
                        weight += w;
                    }
                }
            }
        }
        (weight > 0.0).then(|| sum.map(|s| s / weight))
    }
}

fn cell_of(p: DVec3, cell: f64) -> [i64; 3] {
    (p / cell).floor().as_i64vec3().to_array()
}
