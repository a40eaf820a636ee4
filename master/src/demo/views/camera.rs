//! The projector-role consistency check on the demo's outputs, measured by
//! the cabinet's camera: the projectors' values through the true
//! projectors onto the real objects, against the all-virtual target.

use super::*;

/// The projector-role consistency check measured on the demo's outputs:
/// the projectors' values sent through the true projectors (direct light
/// only) onto the real objects with their true reflectance, seen by the
/// cabinet's `camera`, against the target (true reflectance times the
/// virtual lights' irradiance with the virtual shadows).
pub(in crate::demo) struct CameraConsistency {
    /// The camera's view: [`ObserverView::real`] is what it measures.
    pub view: ObserverView,
    /// Exposure that maps the target's 99th-percentile channel to 0.9.
    pub exposure: f64,
    /// Relative RMSE over the compared pixels: real surfaces that a
    /// projector reaches, off the camera's silhouette, facet and shadow
    /// edges and reach edges, off the surfaces a projector lights from a
    /// pixel on one of its edges, and outside every tracked eye's
    /// occlusion shadow (the render crate's check leaves the last two out
    /// too).
    pub rel_rmse: f64,
    /// The same per real object (name, value).
    pub per_object: Vec<(String, f64)>,
    /// Compared pixels over the camera's pixels that show a real surface.
    pub compared_fraction: f64,
    /// With complete light transport, the noise over the compared pixels
    /// ([`noise`]).
    pub noise: Option<TruthNoise>,
    /// With complete light transport, the interreflection's share of what
    /// it measures over the compared pixels ([`interreflection_share`]).
    pub interreflection_share: Option<f64>,
}

/// [`CameraConsistency`] of `outputs` at `state`, seen by `truth`'s
/// camera `camera` (at the demo resolution).
pub(in crate::demo) fn camera_consistency(
    truth: &Showcase,
    state: &FrameState,
    outputs: &Outputs,
    camera: usize,
    transport: Transport,
) -> Result<CameraConsistency> {
    let device = &truth
        .cameras
        .get(camera)
        .with_context(|| format!("the scene has no camera {camera}"))?
        .device;
    // No mirror: the camera is no tracked eye, so every eye's occlusion
    // shadow counts as unfillable and is left out.
    let Simulated {
        view,
        projector_edges,
        complete,
    } = simulate(truth, state, outputs, device, None, transport)?;
    let n = view.covered.data.len();
    let real = |i: usize| view.covered.data[i] && !view.sees_virtual.data[i];
    let mask = Image {
        width: view.covered.width,
        height: view.covered.height,
        data: (0..n)
            .map(|i| {
                real(i)
                    && view.reachable.data[i]
                    && !(view.edge.data[i]
                        || view.reach_edge.data[i]
                        || projector_edges.data[i]
                        || view.unfillable.data[i])
            })
            .collect(),
    };
    let compared = mask.data.iter().filter(|m| **m).count();
    let real_pixels = (0..n).filter(|&i| real(i)).count();
    let rel_rmse = metrics::relative_rmse(&view.composite, &view.target, Some(&mask))
        .with_context(|| format!("camera {camera} at frame {}", state.frame))?;
    Ok(CameraConsistency {
        noise: noise(complete.as_ref(), &mask),
        interreflection_share: interreflection_share(complete.as_ref(), &mask),
        exposure: exposure(&view)
            .with_context(|| format!("camera {camera} sees no object at frame {}", state.frame))?,
        per_object: per_object_rel_rmse(truth, &view, &mask, true),
        compared_fraction: compared as f64 / real_pixels.max(1) as f64,
        rel_rmse,
        view,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camera's check on the CPU reference maps of the default demo
    /// scene (calibrated = true devices) meets the check's 1% bound, and
    /// the same check fails maps drawn without the virtual shadows
    /// (measured at frame 60: 0.0052 over 72% of the real pixels,
    /// unshadowed 0.069).
    #[test]
    fn camera_consistency_holds_for_reference_maps_and_fails_unshadowed_ones() {
        use crate::cluster::commands::walk_tracking;
        use crate::cluster::{Show, Tracking};
        use showcase_proto::config::TrackingSource;

        let truth = crate::scene_file::load_scene(&crate::demo::default_scene()).unwrap();
        let truth = at_demo_resolution(&truth).unwrap();
        let tracker =
            crate::tracking::Tracker::new(&walk_tracking(&truth, TrackingSource::Scripted), &truth)
                .unwrap();
        let mut show = Show::new(
            Tracking::Scripted(tracker),
            crate::demo::INTERACTIVE_HZ as f64,
        );
        // Walk up to frame 60: a body is acquired from consistent samples.
        for f in 0..60 {
            show.frame_state(f, 0.0, &truth, 1);
        }
        let (state, _) = show.frame_state(60, 0.0, &truth, 1);
        let frame = FrameScene::resolve(&truth, &state).unwrap();
        let occluders = Occluders::new(&frame).unwrap();
        let outputs = |options: ProjectorOptions| -> Outputs {
            let mut out = Outputs {
                projectors: Vec::new(),
                projector_edges: Vec::new(),
                faces: Vec::new(),
                reference_clipped: Vec::new(),
                profiles: Vec::new(),
                // The nodes encode through the devices themselves.
                projector_profiles: truth
                    .projectors
                    .iter()
                    .map(|p| p.response.clone())
                    .collect(),
            };
            for p in &truth.projectors {
                let map = irradiance_map_cpu(&frame, &occluders, p, options).unwrap();
                out.projector_edges
                    .push(projector_edges(&truth, &occluders, p, &map.state).unwrap());
                out.projectors.push(map.value);
            }
            out
        };
        let right = camera_consistency(
            &truth,
            &state,
            &outputs(ProjectorOptions::default()),
            0,
            Transport::Direct,
        )
        .unwrap();
        assert!(right.rel_rmse <= 0.01, "reference maps: {}", right.rel_rmse);
        assert!(right.compared_fraction > 0.6, "{}", right.compared_fraction);
        let unshadowed = ProjectorOptions {
            shadows: false,
            ..ProjectorOptions::default()
        };
        let wrong =
            camera_consistency(&truth, &state, &outputs(unshadowed), 0, Transport::Direct).unwrap();
        assert!(wrong.rel_rmse > 0.05, "unshadowed maps: {}", wrong.rel_rmse);
    }
}
