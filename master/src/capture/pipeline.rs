//! The capture pipeline: radiance maps from K frames, the projector fit on
//! a reference target, and reflectance by the naive (paper), piecewise
//! (paper, section 3.5) or interreflection-corrected method.

use super::scenes;
use anyhow::Context;
use glam::{DVec3, Vec3};
use showcase_light::hardware::{CameraDevice, ProjectorDevice};
use showcase_light::reflectance::{
    CalibrationLevel, CorrectionParams, ExtractParams, ProjectorFit, ReflectanceMap, WholeCapture,
    blend_weights, estimate_projector, extract_reflectance, indirect_irradiance,
};
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{
    DeviceRays, Image, IntensityImage, IntensityLight, ObjectFilter, RgbImage, SceneGeometry,
    render_intensity, world_matrix,
};
use showcase_proto::capture::Pattern;
use showcase_proto::{ProjectorResponse, Showcase};

/// How reflectance is extracted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The whole scene lit at once, `I_rad / I_int` (paper 3.4).
    Naive,
    /// One piece (object) lit and extracted at a time (paper 3.5).
    Piecewise,
    /// The whole scene lit, secondary scattering removed by the
    /// inverse-radiosity fixed point.
    Corrected,
}

impl Method {
    /// The bench's name of the method.
    pub fn name(self) -> &'static str {
        match self {
            Method::Naive => "naive",
            Method::Piecewise => "piecewise",
            Method::Corrected => "corrected",
        }
    }
}

/// Where eta and the black level come from; [`EtaMode::resolve`] turns
/// a mode into the values a capture uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EtaMode {
    /// Given (e.g. the sim's true values).
    Known {
        /// Projector intensity eta (W/sr).
        eta: f64,
        /// Black level (W/sr).
        black_level: f64,
    },
    /// Taken from the response of the scene's projector 0: in the
    /// simulated showcase, the true values.
    FromScene,
    /// Fitted with Brent's method on the reference target.
    Estimated,
}

/// Eta and the black level a capture uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectorLevels {
    /// Projector intensity eta (W/sr).
    pub eta: f64,
    /// Black level (W/sr).
    pub black_level: f64,
}

impl ProjectorLevels {
    /// The levels of a projector's photometric `response`.
    pub fn of(response: &ProjectorResponse) -> Self {
        Self {
            eta: response.eta as f64,
            black_level: response.black_level as f64,
        }
    }
}

impl EtaMode {
    /// The eta and black level of this mode for a capture of `scene`: the
    /// known values, projector 0's response, or the result of `fit` (the
    /// fit on the reference target, called only when estimated).
    pub fn resolve(
        self,
        scene: &Showcase,
        fit: impl FnOnce() -> anyhow::Result<ProjectorFit>,
    ) -> anyhow::Result<ProjectorLevels> {
        Ok(match self {
            EtaMode::Known { eta, black_level } => ProjectorLevels { eta, black_level },
            EtaMode::FromScene => {
                let projector = scene.projectors.first().context("no projector")?;
                ProjectorLevels::of(&projector.response)
            }
            EtaMode::Estimated => {
                let fit = fit()?;
                ProjectorLevels {
                    eta: fit.eta,
                    black_level: fit.black_level,
                }
            }
        })
    }
}

/// Settings of one capture.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureConfig {
    /// Frames averaged per radiance map (K).
    pub frames: u32,
    /// Extraction method.
    pub method: Method,
    /// Source of eta and the black level.
    pub eta: EtaMode,
    /// Floor and phi_max.
    pub extract: ExtractParams,
    /// Interreflection correction settings.
    pub correction: CorrectionParams,
    /// Projector pixels by which a piece's light mask is grown, so the
    /// piece's edges are fully lit.
    pub piece_dilate_px: u32,
    /// Piecewise capture lights one object within one tile of an
    /// `n x n` grid over the projector image at a time: the smaller the
    /// piece, the less of its own light comes back to it from the rest of
    /// a concave scene. 6 (36 tiles per object): on the Cornell box at 16
    /// frames this gives 3.6x lower interreflection error than naive
    /// capture, where 4 gave 3.0x at half the time.
    pub piece_tiles: u32,
    /// Width in pixels of the blend-weight ramp at blank borders.
    pub border_px: f64,
    /// Samples per pixel of the reference target's sim.
    pub reference_samples: u32,
}

impl CaptureConfig {
    /// [`EtaMode::resolve`] for a capture of `scene` with this config,
    /// fitting on `scene`'s reference target ([`calibrate_reference`]) at
    /// this config's frames and reference samples when estimated.
    pub fn resolve_eta(&self, scene: &Showcase) -> anyhow::Result<ProjectorLevels> {
        self.eta.resolve(scene, || {
            calibrate_reference(scene, self.frames, self.reference_samples)
        })
    }
}

impl Default for CaptureConfig {
    fn default() -> Self {
        Self {
            frames: 16,
            method: Method::Corrected,
            eta: EtaMode::Estimated,
            extract: ExtractParams::default(),
            correction: CorrectionParams::default(),
            piece_dilate_px: 1,
            piece_tiles: 6,
            border_px: 3.0,
            reference_samples: 4,
        }
    }
}

/// The result of a capture.
#[derive(Clone, Debug)]
pub struct CaptureOutcome {
    /// `I_ref`, 0 where invalid.
    pub reflectance: RgbImage,
    /// Valid pixels.
    pub valid: Image<bool>,
    /// The stored map (with blend weights).
    pub map: ReflectanceMap,
    /// The intensity image of the whole scene (surfaces per pixel).
    pub intensity: IntensityImage,
    /// Radiance maps captured (one per piece for piecewise capture).
    pub pieces: usize,
    /// Eta used.
    pub eta: f64,
    /// Black level used.
    pub black_level: f64,
}

/// Show `image` and average `frames` frames into a radiance map `I_rad`
/// (`pi * L`, see the module docs of `capture`).
pub fn capture_radiance<P: ProjectorDevice, C: CameraDevice>(
    projector: &mut P,
    camera: &mut C,
    image: &RgbImage,
    frames: u32,
) -> anyhow::Result<RgbImage> {
    projector.show(image)?;
    average_frames(projector.wheel_period_s(), camera, frames)
}

/// [`capture_radiance`] of a [`Pattern`]: the projector shows it with
/// [`ProjectorDevice::show_pattern`] (a projector behind the network
/// receives the pattern, not an image).
pub fn capture_radiance_pattern<P: ProjectorDevice, C: CameraDevice>(
    projector: &mut P,
    camera: &mut C,
    pattern: &Pattern,
    frames: u32,
) -> anyhow::Result<RgbImage> {
    projector.show_pattern(pattern)?;
    average_frames(projector.wheel_period_s(), camera, frames)
}

/// Average `frames` frames of `camera`, spread over the display period
/// `period` ([`CameraDevice::capture_series`]), into `I_rad`.
fn average_frames<C: CameraDevice>(
    period: f64,
    camera: &mut C,
    frames: u32,
) -> anyhow::Result<RgbImage> {
    let k = frames.max(1);
    let r = camera.response().clone();
    let exposure = r.exposure_s as f64;
    let scale = std::f64::consts::PI / (r.gain as f64 * exposure);
    anyhow::ensure!(
        scale.is_finite() && scale > 0.0,
        "camera gain {} / exposure {exposure} s",
        r.gain
    );
    let d = camera.device().clone();
    let mut sum = vec![DVec3::ZERO; (d.width * d.height) as usize];
    let captured = camera.capture_series(exposure, period, k)?;
    anyhow::ensure!(
        captured.len() == k as usize,
        "the camera returned {} of {k} frames",
        captured.len()
    );
    for frame in captured {
        anyhow::ensure!(
            frame.codes.data.len() == sum.len(),
            "a {}x{} frame from a {}x{} camera",
            frame.codes.width,
            frame.codes.height,
            d.width,
            d.height
        );
        let max = ((1u32 << frame.bits.clamp(1, 16)) - 1) as f64;
        for (s, c) in sum.iter_mut().zip(&frame.codes.data) {
            let signal: [f64; 3] = std::array::from_fn(|ch| r.decode(ch, c[ch] as f64 / max));
            *s += DVec3::from(signal);
        }
    }
    Ok(Image {
        width: d.width,
        height: d.height,
        data: sum
            .iter()
            .map(|s| (*s * scale / k as f64).as_vec3())
            .collect(),
    })
}

/// Set the camera gain of `scene` as an operator would (paper 3.2): so
/// the brightest pixel of the white-lit scene, estimated from the sim's
/// direct light plus 30% for interreflection and the colour wheel's worst
/// partial turn, lands at 90% of full scale.
pub fn adjust_camera_gain(scene: &mut Showcase, sim: &SimShowcase) -> anyhow::Result<()> {
    let projector = scene.projectors.first().context("no projector")?;
    let camera = scene.cameras.first().context("no camera")?;
    let geometry = SceneGeometry::build(scene, &ObjectFilter::Real)?;
    let light = IntensityLight::projector(
        &projector.device,
        Vec3::ONE,
        (projector.response.eta + projector.response.black_level) as f64,
    )?;
    let img = render_intensity(
        &geometry,
        &DeviceRays::new(&camera.device)?,
        &light,
        &ObjectFilter::Real,
    );
    let (truth, _) = sim.ground_truth(0)?;
    let peak = img
        .intensity
        .data
        .iter()
        .zip(&truth.data)
        .map(|(e, a)| (*e * *a).max_element() as f64 / std::f64::consts::PI)
        .fold(0.0, f64::max);
    anyhow::ensure!(peak > 0.0, "the projector lights nothing the camera sees");
    let wheel = 4.0 / 3.0;
    let c = &mut scene.cameras[0];
    c.response.gain = (0.9 / (peak * 1.3 * wheel * c.response.exposure_s as f64)) as f32;
    Ok(())
}

/// Fit eta and the black level (Brent, `reflectance::eta`) from captures
/// of a reference target of albedo `albedo` (scene `reference`, seen by
/// `projector` and `camera`) at pixel values 1 and 0.5; `gamma` is the
/// projector's calibrated response exponent.
pub fn calibrate_projector<P: ProjectorDevice, C: CameraDevice>(
    reference: &Showcase,
    projector: &mut P,
    camera: &mut C,
    albedo: Vec3,
    gamma: f64,
    frames: u32,
) -> anyhow::Result<ProjectorFit> {
    let geometry = SceneGeometry::build(reference, &ObjectFilter::Real)?;
    let rays = DeviceRays::new(camera.device())?;
    let unit = IntensityLight::projector(projector.device(), Vec3::ONE, 1.0)?;
    let g = render_intensity(&geometry, &rays, &unit, &ObjectFilter::Real);
    let floor = showcase_light::reflectance::intensity_floor(&g.intensity, 1e-2);
    let phi_max = 60f64.to_radians();
    let mask = Image {
        width: g.intensity.width,
        height: g.intensity.height,
        data: g
            .surface
            .data
            .iter()
            .zip(&g.intensity.data)
            .map(|(s, e)| {
                s.is_some_and(|s| s.lit && s.phi <= phi_max) && e.min_element() as f64 > floor
            })
            .collect(),
    };
    let rho = Image::new(g.intensity.width, g.intensity.height, albedo);
    let mut levels = Vec::new();
    for v in [1.0f32, 0.5] {
        let i_rad =
            capture_radiance_pattern(projector, camera, &Pattern::Full { level: [v; 3] }, frames)?;
        levels.push(CalibrationLevel {
            response: (v as f64).powf(gamma),
            i_rad,
        });
    }
    // Initial guess: the ratio of mean captured to mean unit-light radiance.
    let (mut num, mut den) = (0.0, 0.0);
    for (k, m) in mask.data.iter().enumerate() {
        if *m {
            num += levels[0].i_rad.data[k].as_dvec3().element_sum();
            den += (rho.data[k] * g.intensity.data[k]).as_dvec3().element_sum();
        }
    }
    let guess = if den > 0.0 && num > 0.0 {
        num / den
    } else {
        1.0
    };
    Ok(estimate_projector(
        &levels,
        &g.intensity,
        &rho,
        &mask,
        guess,
    )?)
}

/// Capture the reflectance of `model`'s real objects (the registered
/// geometry) with a projector of known `gamma` and the eta and black
/// level `levels` (`config.eta` resolved, see
/// [`CaptureConfig::resolve_eta`]), by `config.method`.
pub fn capture_map<P: ProjectorDevice, C: CameraDevice>(
    model: &Showcase,
    projector: &mut P,
    camera: &mut C,
    levels: ProjectorLevels,
    config: &CaptureConfig,
) -> anyhow::Result<CaptureOutcome> {
    let ProjectorLevels { eta, black_level } = levels;
    let geometry = SceneGeometry::build(model, &ObjectFilter::Real)?;
    let rays = DeviceRays::new(camera.device())?;
    let pdev = projector.device().clone();
    let light = IntensityLight::projector(&pdev, Vec3::ONE, eta + black_level)?;
    let intensity = render_intensity(&geometry, &rays, &light, &ObjectFilter::Real);
    let white = Pattern::Full { level: [1.0; 3] };
    let mut radiance_maps = 1;
    let (reflectance, valid) = match config.method {
        Method::Naive | Method::Corrected => {
            let i_rad = capture_radiance_pattern(projector, camera, &white, config.frames)?;
            let (rho, valid) =
                extract_reflectance(&i_rad, &intensity.intensity, &intensity, &config.extract)?;
            if config.method == Method::Naive {
                (rho, valid)
            } else {
                let e_ind = indirect_irradiance(
                    &geometry,
                    &rays,
                    &light,
                    &WholeCapture {
                        i_rad: &i_rad,
                        i_int: &intensity.intensity,
                        valid: &valid,
                    },
                    &config.correction,
                )?;
                let mut irradiance = intensity.intensity.clone();
                for (e, i) in irradiance.data.iter_mut().zip(&e_ind.data) {
                    *e += *i;
                }
                extract_reflectance(&i_rad, &irradiance, &intensity, &config.extract)?
            }
        }
        Method::Piecewise => {
            let prays = DeviceRays::new(&pdev)?;
            let n = config.piece_tiles.max(1);
            let tile_of = |x: u32, y: u32| (x * n / pdev.width) * n + y * n / pdev.height;
            // Piece of each projector pixel: (object its centre ray hits, tile).
            let piece_of: Image<Option<(u32, u32)>> =
                Image::from_fn(pdev.width, pdev.height, |x, y| {
                    let ray = prays.pixel_ray(x, y)?;
                    geometry
                        .closest_hit(&ray, 0.0, f64::INFINITY)
                        .map(|h| (h.object, tile_of(x, y)))
                });
            // Piece of each camera pixel: its object and the tile its point
            // projects to.
            let camera_piece: Vec<Option<(u32, u32)>> = intensity
                .surface
                .data
                .iter()
                .map(|s| {
                    let s = (*s)?;
                    let (x, y) = prays.pixel_of(s.point)?;
                    Some((s.object, tile_of(x, y)))
                })
                .collect();
            let mut pieces: Vec<(u32, u32)> = camera_piece.iter().flatten().copied().collect();
            pieces.sort_unstable();
            pieces.dedup();
            let mut rho = Image::new(rays.device().width, rays.device().height, Vec3::ZERO);
            let mut valid = Image::new(rho.width, rho.height, false);
            radiance_maps = pieces.len();
            for piece in pieces {
                let mask = dilate(&piece_of.map(|p| *p == Some(piece)), config.piece_dilate_px);
                let pattern =
                    Pattern::mask(mask.width, mask.height, mask.data.iter().copied(), [1.0; 3]);
                let i_rad = capture_radiance_pattern(projector, camera, &pattern, config.frames)?;
                let lit = ObjectFilter::Indices(vec![piece.0 as usize]);
                let piece_int = render_intensity(&geometry, &rays, &light, &lit);
                let (r, v) =
                    extract_reflectance(&i_rad, &piece_int.intensity, &piece_int, &config.extract)?;
                for (k, p) in camera_piece.iter().enumerate() {
                    if *p == Some(piece) {
                        rho.data[k] = r.data[k];
                        valid.data[k] = v.data[k];
                    }
                }
            }
            (rho, valid)
        }
    };
    let weight = blend_weights(
        &valid,
        &intensity.surface,
        config.extract.phi_max_deg,
        config.border_px,
    )?;
    let transforms = model
        .objects
        .iter()
        .map(|o| world_matrix(&o.transform).unwrap_or(glam::DMat4::IDENTITY))
        .collect();
    let map = ReflectanceMap::new(
        reflectance.clone(),
        weight,
        &intensity,
        camera.device().clone(),
        transforms,
    )?;
    Ok(CaptureOutcome {
        reflectance,
        valid,
        map,
        intensity,
        pieces: radiance_maps,
        eta,
        black_level,
    })
}

/// Capture in the simulated showcase `sim` of `scene` (projector 0,
/// camera 0): fit eta on the reference target first when
/// `config.eta` is `Estimated`.
pub fn capture_reflectance(
    scene: &Showcase,
    sim: &SimShowcase,
    config: &CaptureConfig,
) -> anyhow::Result<CaptureOutcome> {
    anyhow::ensure!(!scene.projectors.is_empty(), "the scene has no projector");
    let levels = config.resolve_eta(scene)?;
    let mut projector = sim.projector(0)?;
    let mut camera = sim.camera(0)?;
    capture_map(scene, &mut projector, &mut camera, levels, config)
}

/// The projector fit on the reference target of `scene`'s rig (a separate
/// sim of the target alone).
pub fn calibrate_reference(
    scene: &Showcase,
    frames: u32,
    samples: u32,
) -> anyhow::Result<ProjectorFit> {
    let gamma = scene
        .projectors
        .first()
        .context("no projector")?
        .response
        .gamma as f64;
    let reference = scenes::reference_scene(scene)?;
    let sim = SimShowcase::new(
        &reference,
        SimConfig {
            samples_per_pixel: samples,
            ..SimConfig::default()
        },
    )?;
    calibrate_projector(
        &reference,
        &mut sim.projector(0)?,
        &mut sim.camera(0)?,
        Vec3::splat(scenes::REFERENCE_ALBEDO),
        gamma,
        frames,
    )
}

/// Grow a mask by `r` pixels (square neighbourhood).
fn dilate(mask: &Image<bool>, r: u32) -> Image<bool> {
    let r = r as i64;
    Image::from_fn(mask.width, mask.height, |x, y| {
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                xx >= 0 && yy >= 0 && mask.get(xx as u32, yy as u32).copied().unwrap_or(false)
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each mode gives its own values, and only an estimate runs the fit.
    #[test]
    fn eta_modes_resolve_to_their_levels() {
        let scene = scenes::plate_scene((8, 8), false);
        let response = &scene.projectors[0].response;
        let truth = ProjectorLevels {
            eta: response.eta as f64,
            black_level: response.black_level as f64,
        };
        let fit = ProjectorFit {
            eta: 0.9,
            black_level: 0.02,
            mse: 0.0,
        };
        let unused = || -> anyhow::Result<ProjectorFit> { panic!("fit run for a given eta") };
        let known = EtaMode::Known {
            eta: 2.0,
            black_level: 0.5,
        };
        assert_eq!(
            known.resolve(&scene, unused).unwrap(),
            ProjectorLevels {
                eta: 2.0,
                black_level: 0.5
            }
        );
        assert_eq!(EtaMode::FromScene.resolve(&scene, unused).unwrap(), truth);
        assert_eq!(
            EtaMode::Estimated.resolve(&scene, || Ok(fit)).unwrap(),
            ProjectorLevels {
                eta: 0.9,
                black_level: 0.02
            }
        );
        let bare = Showcase::default();
        let e = EtaMode::FromScene.resolve(&bare, unused).unwrap_err();
        assert!(e.to_string().contains("no projector"), "{e}");
    }
}
