//! Photometric calibration through the simulated cabinet
//! (`showcase_master::calibrate::photometric`): a camera in the observer's
//! place measures face-0's CRT and beam splitter, which the demo scene
//! deliberately mismatches, and the profile it fits must show what the
//! true devices show; a camera that moves, a saturated bracket, a CRT
//! whose light falls, and a worse fit than the profile in place are caught.
//! The same camera then measures each projector's light per channel
//! (`calibrate_projector`), with the same checks.

use anyhow::Result;
use glam::{DVec3, Vec3};
use showcase_light::observer_view::complete::CompleteOptions;
use showcase_light::render::FrameScene;
use showcase_master::calibrate::photometric::{
    CrtPattern, FaceCalibration, Lamp, MirrorCamera, PhotometricOptions, ProjectorCalibration,
    SimMirrorCamera, Spot, calibrate_face, calibrate_projector,
};
use showcase_master::demo::photometric::projector_curve_error;
use showcase_proto::{Camera, CrtPhotometry, CrtResponse, PinholeDevice, Showcase};

/// The demo cabinet with its projectors at half their width and height
/// (the demo's resolution).
fn cabinet() -> Showcase {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml");
    let mut s = showcase_master::scene_file::load_scene(&path).expect("the demo scene loads");
    for p in &mut s.projectors {
        let d = &p.device;
        p.device = showcase_master::capture::resize_device(d, d.width / 2, d.height / 2).unwrap();
    }
    s
}

/// The scene's camera on a tripod at the observer's left eye, looking
/// where the observer looks, at 160x120 pixels (the bench's).
fn tripod(scene: &Showcase) -> Camera {
    let head = scene.observers[0].head;
    let eye = showcase_proto::Observer::eyes(&head, scene.observers[0].ipd)[0].as_dvec3();
    let forward = (head.orientation * Vec3::NEG_Z).as_dvec3();
    let mut device = PinholeDevice::look_at(eye, eye + forward, DVec3::Y, 30.0, 160, 120);
    device.near = 0.05;
    device.far = 10.0;
    Camera {
        name: "tripod".into(),
        device,
        response: scene.cameras[0].response.clone(),
    }
}

fn options() -> CompleteOptions {
    CompleteOptions {
        paths_per_point: 16,
        seed: 5,
    }
}

/// What a [`Twisted`] rig does to the pattern it is asked to show (shot
/// number, pattern, and the exposures, changeable), and to the frames it
/// returns (called again with them; empty the first time).
type Twist =
    Box<dyn FnMut(usize, CrtPattern, &mut Vec<Vec<[u16; 3]>>, &mut Vec<f64>) -> CrtPattern>;

/// Calibrate face-0 with the simulated rig, twisted by `twist`.
fn calibrate(
    twist: Option<Twist>,
    previous: &CrtPhotometry,
) -> Result<(FaceCalibration, CrtPhotometry)> {
    let scene = cabinet();
    let camera = tripod(&scene);
    let frame = FrameScene::from_parts(scene.clone(), &[camera.device.center()])?;
    let face = &scene.faces[0];
    let mut rig = Twisted {
        inner: SimMirrorCamera::new(&frame, face, &camera, options())?,
        shots: 0,
        twist: twist.unwrap_or_else(|| Box::new(|_, crt, _, _| crt)),
    };
    let calibration = calibrate_face(
        &mut rig,
        &scene,
        face,
        &camera.device,
        previous,
        &PhotometricOptions::default(),
    )?;
    Ok((calibration, face.photometry))
}

/// The largest relative error of `profile`'s light through the mirror
/// against `truth`'s over drive 0.1 to 1.
fn curve_error(profile: &CrtPhotometry, truth: &CrtPhotometry) -> f64 {
    (10..=100)
        .flat_map(|k| (0..3).map(move |c| (k, c)))
        .map(|(k, c)| {
            let mut d = Vec3::ZERO;
            d[c] = k as f32 / 100.0;
            f64::from(((profile.seen(d)[c] - truth.seen(d)[c]) / truth.seen(d)[c]).abs())
        })
        .fold(0.0, f64::max)
}

#[test]
fn the_fitted_profile_shows_what_the_true_crt_and_splitter_show() -> Result<()> {
    let nominal = CrtPhotometry::nominal(2.2);
    let (cal, truth) = calibrate(None, &nominal)?;
    let error = curve_error(&cal.profile, &truth);
    // The nominal profile is far off (the splitter's R / T alone is 0.6).
    let before = curve_error(&nominal, &truth);
    assert!(
        error < 0.03,
        "fitted curve off by {error:.4} (nominal {before:.3})"
    );
    assert!(before > 0.3, "nominal curve off by only {before:.3}");
    assert!(!cal.kept_previous);
    assert!(
        cal.held_out_error < 0.03,
        "held out {:.4}",
        cal.held_out_error
    );
    assert!(cal.held_out_error_before > 0.3);
    assert_eq!(cal.profile, cal.fitted);
    // The reference spot: what the camera measured over what it predicts
    // is the camera's scale times the transmission, per channel; between
    // channels only the camera's scales differ, so it is not 0 or NaN.
    assert!(
        cal.reference.measured.iter().all(|m| *m > 0.0),
        "{:?}",
        cal.reference
    );
    Ok(())
}

/// A rig that changes what it is asked, or what it returns.
struct Twisted<'a> {
    inner: SimMirrorCamera<'a>,
    shots: usize,
    twist: Twist,
}

impl MirrorCamera for Twisted<'_> {
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }
    fn levels(&self) -> u32 {
        self.inner.levels()
    }
    fn base_exposure_s(&self) -> f64 {
        self.inner.base_exposure_s()
    }
    fn capture(
        &mut self,
        crt: CrtPattern,
        spot: Option<Spot>,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        let mut exposures = exposures_s.to_vec();
        let asked = (self.twist)(self.shots, crt, &mut Vec::new(), &mut exposures);
        let mut frames = self.inner.capture(asked, spot, &exposures)?;
        (self.twist)(self.shots, crt, &mut frames, &mut exposures.clone());
        self.shots += 1;
        Ok(frames)
    }
}

fn error_of(result: Result<(FaceCalibration, CrtPhotometry)>) -> String {
    match result {
        Ok((cal, _)) => panic!("calibrated: {:?}", cal.profile),
        Err(e) => format!("{e:#}"),
    }
}

#[test]
fn a_camera_that_moves_during_the_calibration_is_an_error() {
    // From the third shot on, every frame is shifted by 3 pixels.
    let e = error_of(calibrate(
        Some(Box::new(|shot, crt, frames: &mut Vec<Vec<[u16; 3]>>, _| {
            if shot >= 3 {
                for f in frames.iter_mut() {
                    f.rotate_right(3);
                }
            }
            crt
        })),
        &CrtPhotometry::nominal(2.2),
    ));
    assert!(e.contains("moved"), "{e}");
}

/// The error of a calibration whose every exposure time is `factor`
/// times the one asked for.
fn exposed_by(factor: f64) -> String {
    error_of(calibrate(
        Some(Box::new(move |_, crt, _, exposures: &mut Vec<f64>| {
            for t in exposures.iter_mut() {
                *t *= factor;
            }
            crt
        })),
        &CrtPhotometry::nominal(2.2),
    ))
}

#[test]
fn a_saturated_bracket_is_an_error_saying_what_to_do() {
    let e = exposed_by(1000.0);
    assert!(
        e.contains("shorter exposures") || e.contains("saturated"),
        "{e}"
    );
}

#[test]
fn an_under_exposed_bracket_is_an_error_saying_what_to_do() {
    let e = exposed_by(1e-5);
    assert!(
        e.contains("longer exposures") || e.contains("under-exposed"),
        "{e}"
    );
}

#[test]
fn a_crt_whose_light_falls_as_its_drive_rises_is_an_error() {
    // The CRT shows 1 - d when asked for d.
    let e = error_of(calibrate(
        Some(Box::new(|_, crt, _, _| match crt {
            CrtPattern::Uniform(d) => CrtPattern::Uniform(Vec3::ONE - d),
            other => other,
        })),
        &CrtPhotometry::nominal(2.2),
    ));
    assert!(e.contains("falls"), "{e}");
}

#[test]
fn a_fit_worse_than_the_profile_in_place_keeps_that_profile() -> Result<()> {
    // The fitted levels (k / 12) come out at 80 % of the drive asked, the
    // held-out ones as asked: the fit is wrong and the held-out levels
    // show it against the true devices, the profile in place.
    let truth = cabinet().faces[0].photometry;
    let (cal, _) = calibrate(
        Some(Box::new(|_, crt, _, _| match crt {
            CrtPattern::Uniform(d) if (d.x * 12.0 - (d.x * 12.0).round()).abs() < 1e-4 => {
                CrtPattern::Uniform(d * 0.8)
            }
            other => other,
        })),
        &truth,
    )?;
    assert!(cal.kept_previous, "{cal:?}");
    assert_eq!(cal.profile, truth);
    assert!(cal.held_out_error > cal.held_out_error_before);
    Ok(())
}

/// What a [`LampTwisted`] rig does to the lamp it is asked to show (shot
/// number, lamp, and the exposures, changeable), and to the frames it
/// returns (called again with them; empty the first time).
type LampTwist = Box<dyn FnMut(usize, Lamp, &mut Vec<Vec<[u16; 3]>>, &mut Vec<f64>) -> Lamp>;

/// A rig that changes what a projector is asked to show, or what it
/// returns.
struct LampTwisted<'a, 'b> {
    inner: &'b mut SimMirrorCamera<'a>,
    shots: usize,
    twist: LampTwist,
}

impl MirrorCamera for LampTwisted<'_, '_> {
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }
    fn levels(&self) -> u32 {
        self.inner.levels()
    }
    fn base_exposure_s(&self) -> f64 {
        self.inner.base_exposure_s()
    }
    fn capture(
        &mut self,
        crt: CrtPattern,
        spot: Option<Spot>,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        self.inner.capture(crt, spot, exposures_s)
    }
    fn capture_projector(
        &mut self,
        projector: usize,
        lamp: Lamp,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        let mut exposures = exposures_s.to_vec();
        let asked = (self.twist)(self.shots, lamp, &mut Vec::new(), &mut exposures);
        let mut frames = self.inner.capture_projector(projector, asked, &exposures)?;
        (self.twist)(self.shots, lamp, &mut frames, &mut exposures.clone());
        self.shots += 1;
        Ok(frames)
    }
}

/// The camera's recovered response, from face-0's calibration (once for
/// every test: the projector's calibration takes it as given).
fn recovered_response() -> &'static showcase_master::calibrate::photometric::RecoveredResponse {
    static RESPONSE: std::sync::OnceLock<
        showcase_master::calibrate::photometric::RecoveredResponse,
    > = std::sync::OnceLock::new();
    RESPONSE.get_or_init(|| {
        calibrate(None, &CrtPhotometry::nominal(2.2))
            .expect("face-0 calibrates")
            .0
            .response
    })
}

/// Calibrate projector 0 with the simulated rig at face-0, twisted by
/// `twist`, its node's profile in place `previous` (`None`: its model);
/// with the true device's curve.
fn calibrate_lamp(
    twist: Option<LampTwist>,
    previous: Option<CrtResponse>,
) -> Result<(ProjectorCalibration, CrtResponse)> {
    let response = recovered_response();
    let scene = cabinet();
    let camera = tripod(&scene);
    let frame = FrameScene::from_parts(scene.clone(), &[camera.device.center()])?;
    let mut sim = SimMirrorCamera::new(&frame, &scene.faces[0], &camera, options())?;
    let mut rig = LampTwisted {
        inner: &mut sim,
        shots: 0,
        twist: twist.unwrap_or_else(|| Box::new(|_, lamp, _, _| lamp)),
    };
    let truth = scene.projectors[0]
        .response
        .photometry
        .expect("the demo scene states projector-0's own light");
    let mut node = scene.projectors[0].clone();
    node.response.photometry = previous;
    let calibration =
        calibrate_projector(&mut rig, 0, &node, response, &PhotometricOptions::default())?;
    Ok((calibration, truth))
}

fn lamp_error_of(result: Result<(ProjectorCalibration, CrtResponse)>) -> String {
    match result {
        Ok((cal, _)) => panic!("calibrated: {:?}", cal.profile),
        Err(e) => format!("{e:#}"),
    }
}

#[test]
fn the_fitted_projector_profile_shows_what_the_true_projector_shows() -> Result<()> {
    let (cal, truth) = calibrate_lamp(None, None)?;
    let worst = |e: [f64; 3]| e.into_iter().fold(0.0, f64::max);
    let error = worst(projector_curve_error(&cal.profile, &truth));
    let model = cabinet().projectors[0].response.model_curve();
    let before = worst(projector_curve_error(&model, &truth));
    // Issue #28's target: within 1 % of the truth over values 0.1 to 1.
    assert!(
        error < 0.01,
        "fitted curve off by {error:.4} (model {before:.3}): {:?} against {truth:?}",
        cal.profile
    );
    assert!(before > 0.2, "the model is off by only {before:.3}");
    for c in 0..3 {
        assert!(
            (cal.profile.gamma[c] - truth.gamma[c]).abs() < 0.03,
            "gamma {:?} against {:?}",
            cal.profile.gamma,
            truth.gamma
        );
        let black = cal.profile.black_level[c] / truth.black_level[c] - 1.0;
        assert!(
            black.abs() < 0.1,
            "black {:?} against {:?}",
            cal.profile.black_level,
            truth.black_level
        );
    }
    assert!(!cal.kept_previous);
    assert!(
        cal.held_out_error < 0.01,
        "held out {:.4}",
        cal.held_out_error
    );
    assert!(cal.held_out_error_before > 0.2);
    assert_eq!(cal.profile, cal.fitted);
    // The node encodes through it: the model's light is what the true
    // device then shows.
    let mut node = cabinet().projectors[0].response.clone();
    node.photometry = Some(cal.profile);
    let mut device = node.clone();
    device.photometry = Some(truth);
    for v in [0.2f32, 0.5, 0.9] {
        let want = node.model(Vec3::splat(v));
        let got = device.light(node.encode(Vec3::splat(v)));
        let off = ((got - want) / want).abs().max_element();
        assert!(off < 0.01, "value {v}: {got} against {want}");
    }
    Ok(())
}

#[test]
fn a_camera_that_moves_during_a_projector_calibration_is_an_error() {
    // From the fourth shot on, every frame is shifted by 3 pixels.
    let e = lamp_error_of(calibrate_lamp(
        Some(Box::new(
            |shot, lamp, frames: &mut Vec<Vec<[u16; 3]>>, _| {
                if shot >= 3 {
                    for f in frames.iter_mut() {
                        f.rotate_right(3);
                    }
                }
                lamp
            },
        )),
        None,
    ));
    assert!(e.contains("moved"), "{e}");
}

/// The error of a projector's calibration whose every exposure time is
/// `factor` times the one asked for.
fn lamp_exposed_by(factor: f64) -> String {
    lamp_error_of(calibrate_lamp(
        Some(Box::new(move |_, lamp, _, exposures: &mut Vec<f64>| {
            for t in exposures.iter_mut() {
                *t *= factor;
            }
            lamp
        })),
        None,
    ))
}

#[test]
fn a_saturated_projector_bracket_is_an_error_saying_what_to_do() {
    let e = lamp_exposed_by(1000.0);
    assert!(
        e.contains("saturated") && e.contains("shorter exposures"),
        "{e}"
    );
}

#[test]
fn an_under_exposed_projector_bracket_is_an_error_saying_what_to_do() {
    let e = lamp_exposed_by(1e-5);
    assert!(
        e.contains("under-exposed") && e.contains("longer exposures"),
        "{e}"
    );
}

#[test]
fn a_projector_whose_light_falls_as_its_value_rises_is_an_error() {
    // Below full white the projector shows 1 - v when asked for v.
    let e = lamp_error_of(calibrate_lamp(
        Some(Box::new(|_, lamp, _, _| match lamp {
            Lamp::Uniform(v) if v < 1.0 => Lamp::Uniform(1.0 - v),
            other => other,
        })),
        None,
    ));
    assert!(e.contains("falls") && e.contains("projector-0"), "{e}");
}

#[test]
fn a_projector_fit_worse_than_the_profile_in_place_keeps_that_profile() -> Result<()> {
    // The fitted values (k / 12, below white) come out at 80 % of the
    // value asked, the held-out ones as asked: the held-out levels show
    // the fit wrong against the true device, the profile in place.
    let truth = cabinet().projectors[0].response.photometry.expect("stated");
    let (cal, _) = calibrate_lamp(
        Some(Box::new(|_, lamp, _, _| match lamp {
            Lamp::Uniform(v) if v < 1.0 && (v * 12.0 - (v * 12.0).round()).abs() < 1e-4 => {
                Lamp::Uniform(v * 0.8)
            }
            other => other,
        })),
        Some(truth),
    )?;
    assert!(cal.kept_previous, "{cal:?}");
    assert_eq!(cal.profile, truth);
    assert!(cal.held_out_error > cal.held_out_error_before);
    Ok(())
}

/// The projector node's device boundary: with a profile its output is the
/// model's values encoded through it (`ProjectorResponse::encode`), pixel
/// for pixel; without one, the values themselves.
#[test]
fn a_projector_node_sends_its_values_through_its_profile() -> Result<()> {
    use anyhow::{Context, ensure};
    use showcase_render::node::renderer::Renderer;
    use showcase_render::render::projector_gpu::ProjectorRenderer;
    let Some(ctx) =
        crate::gpu::gpu_or_skip("a_projector_node_sends_its_values_through_its_profile")?
    else {
        return Ok(());
    };
    let profiled = cabinet();
    let mut model = profiled.clone();
    for p in &mut model.projectors {
        p.response.photometry = None;
    }
    let frame = showcase_proto::FrameState {
        frame: 0,
        time_s: 0.0,
        scene_version: 1,
        heads: model.observers.iter().map(|o| o.head).collect(),
        lights: model.lights.clone(),
        object_transforms: vec![],
        tracking_time_ns: None,
        illumination_version: None,
    };
    let mut r = ProjectorRenderer::new(ctx, 0, 256);
    let mut render = |scene: &Showcase| -> Result<Vec<[f32; 4]>> {
        r.set_scene(1, std::sync::Arc::new(scene.clone()))?;
        Ok(r.render(&frame, scene)?
            .image
            .context("the projector renderer kept no image")?
            .rgba)
    };
    let values = render(&model)?;
    let sent = render(&profiled)?;
    let response = &profiled.projectors[0].response;
    let mut changed = 0;
    for (v, s) in values.iter().zip(&sent) {
        let (v, s) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(s[0], s[1], s[2]));
        let want = response.encode(v);
        ensure!(
            (want - s).abs().max_element() < 1e-6,
            "value {v} sent as {s}, not {want}"
        );
        changed += usize::from((want - v).abs().max_element() > 1e-3);
    }
    ensure!(
        changed * 10 > values.len(),
        "only {changed} of {} pixels changed by the profile",
        values.len()
    );
    Ok(())
}
