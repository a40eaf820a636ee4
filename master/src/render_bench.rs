//! The master's side of `showcase-master bench render`: the bench's scene
//! built from the shared data set's Cornell box and bunny, and its
//! time-against-error plot (the bench itself is
//! `showcase_render::render::bench`).

use crate::plot::{Plot, Point, Series, series_colour};
use crate::scene_file::{SceneError, load_any};
use showcase_proto::Showcase;
use showcase_render::render::bench::Record;
use std::path::Path;

/// The Cornell box's objects that make the bench's real room: its walls,
/// without the blocks and the light.
pub const CORNELL_WALLS: [&str; 5] = ["floor", "ceiling", "back", "right_green", "left_red"];

/// Why the render bench's scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BenchSceneError {
    /// A mesh file could not be loaded.
    #[error(transparent)]
    Load(#[from] SceneError),
    /// The bunny's file holds no object with a mesh.
    #[error("{0} has no mesh")]
    NoMesh(String),
}

/// The render bench's scene ([`showcase_render::render::bench::bench_scene`])
/// from the Cornell box OBJ at `cornell` (the walls of [`CORNELL_WALLS`]
/// it has, with their albedo) and the mesh of the first object of the
/// bunny OBJ at `bunny`.
pub fn bench_scene(cornell: &Path, bunny: &Path) -> Result<Showcase, BenchSceneError> {
    let room = load_any(cornell)?;
    let walls = room
        .objects
        .iter()
        .filter(|o| CORNELL_WALLS.contains(&o.name.as_str()))
        .filter_map(|o| {
            Some((
                o.name.clone(),
                room.mesh(&o.mesh)?.clone(),
                o.material.albedo,
            ))
        })
        .collect();
    let model = load_any(bunny)?;
    let bunny_mesh = model
        .objects
        .first()
        .and_then(|o| model.mesh(&o.mesh))
        .ok_or_else(|| BenchSceneError::NoMesh(bunny.display().to_string()))?
        .clone();
    Ok(showcase_render::render::bench::bench_scene(
        walls, bunny_mesh,
    ))
}

/// The render bench's plot: median frame time against each error it
/// measured (the end-to-end direct-light consistency and the GPU against
/// its CPU reference), a point per role, size and scene variant.
pub fn error_vs_time_plot(records: &[Record]) -> Plot {
    let series = [
        (
            "direct-light consistency (rel RMSE)",
            (|r: &Record| r.consistency_rel_rmse_direct) as fn(&Record) -> Option<f64>,
        ),
        ("GPU against CPU reference (rel RMSE)", |r| {
            r.gpu_cpu_rel_rmse
        }),
    ]
    .into_iter()
    .enumerate()
    .map(|(i, (name, error))| Series {
        name: name.into(),
        colour: series_colour(i).into(),
        joined: false,
        points: records
            .iter()
            .filter_map(|r| {
                let label = format!("{} {}x{} {}", r.role, r.width, r.height, r.scene_variant);
                Some(Point {
                    tooltip: label.clone(),
                    label,
                    ..Point::at(r.median_ms, error(r)?)
                })
            })
            .collect(),
    })
    .filter(|s| !s.points.is_empty())
    .collect();
    Plot {
        title: "bench render: error against frame time".into(),
        x_label: "median frame time (ms)".into(),
        y_label: "relative RMSE".into(),
        series,
        ..Plot::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(role: &str, ms: f64, consistency: Option<f64>, gpu_cpu: Option<f64>) -> Record {
        Record {
            role: role.into(),
            width: 640,
            height: 480,
            scene_variant: "full".into(),
            passes_run: Vec::new(),
            median_ms: ms,
            p99_ms: ms,
            adapter: "test".into(),
            consistency_rel_rmse_direct: consistency,
            gpu_cpu_rel_rmse: gpu_cpu,
            gpu_cpu_rel_rmse_off_edges: None,
            outliers_off_edges: None,
            clipped_fraction: 0.0,
            pass_ms: Default::default(),
            median_with_readback_ms: ms,
            shadow_layers_drawn: 0.0,
            shadow_res: 1024,
        }
    }

    #[test]
    fn the_render_plot_has_a_point_per_measured_error() {
        let records = [
            record("projector", 12.0, Some(0.01), Some(1e-4)),
            record("face", 20.0, None, Some(2e-4)),
            record("projector", 5.0, None, None),
        ];
        let plot = error_vs_time_plot(&records);
        let counts: Vec<usize> = plot.series.iter().map(|s| s.points.len()).collect();
        assert_eq!(counts, [1, 2]);
        assert_eq!(plot.series[1].points[1].label, "face 640x480 full");
        assert_eq!(plot.series[0].points[0].x, 12.0);
        // Timing only (no accuracy): nothing to plot.
        assert!(error_vs_time_plot(&records[2..]).series.is_empty());
    }
}
