//! The photometric calibration rig: a camera on a tripod in an observer's
//! place, looking through a face's beam splitter, while the face's CRT and
//! the projectors show what the calibration asks for.
//!
//! [`MirrorCamera`] is the seam. The simulated showcase implements it here
//! ([`SimMirrorCamera`], the truth behind
//! [`showcase_light::observer_view::photometer`]); a cabinet implements it
//! with its camera, face and projector nodes. The calibration sees only
//! the frames.

use anyhow::{Context, Result};
use glam::Vec3;
use showcase_light::observer_view::ProjectedLight;
use showcase_light::observer_view::complete::CompleteOptions;
use showcase_light::observer_view::photometer::{CrtShows, Photometer};
use showcase_light::render::FrameScene;
use showcase_light::{Image, RgbImage};
use showcase_proto::{Camera, CrtFace};

/// What the face's CRT shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CrtPattern {
    /// Switched off (no light, not even its black level).
    Off,
    /// These drive values over the whole screen.
    Uniform(Vec3),
    /// Drive rising from 0 at the left edge to 1 at the right, in every
    /// channel: a static scene with a wide range of radiance (the exposure
    /// bracket's).
    Ramp,
}

impl CrtPattern {
    /// The drive image for a `width` x `height` screen (`None`: off).
    pub fn drive(&self, width: u32, height: u32) -> Option<RgbImage> {
        match *self {
            Self::Off => None,
            Self::Uniform(d) => Some(Image::new(width, height, d)),
            Self::Ramp => Some(Image::from_fn(width, height, |x, _| {
                Vec3::splat(x as f32 / (width.max(2) - 1) as f32)
            })),
        }
    }
}

/// A square of projector pixels lit at `value` (every other pixel of every
/// projector black).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Which projector (index into the scene's).
    pub projector: usize,
    /// The square's centre pixel.
    pub centre: (u32, u32),
    /// Half its side, in pixels.
    pub half: u32,
    /// Its pixel value, every channel.
    pub value: f32,
}

impl Spot {
    /// The projector image showing the spot.
    pub fn image(&self, width: u32, height: u32) -> RgbImage {
        let (cx, cy) = (i64::from(self.centre.0), i64::from(self.centre.1));
        let h = i64::from(self.half);
        Image::from_fn(width, height, |x, y| {
            let inside = (i64::from(x) - cx).abs() <= h && (i64::from(y) - cy).abs() <= h;
            if inside {
                Vec3::splat(self.value)
            } else {
                Vec3::ZERO
            }
        })
    }
}

/// What one projector shows for [`MirrorCamera::capture_projector`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lamp {
    /// No light at all (lamp off or lens capped): not even its black
    /// level.
    Off,
    /// This device value in every pixel and channel.
    Uniform(f32),
}

/// A camera looking through a face's mirror, with the face and the
/// projectors showing what it is asked to.
pub trait MirrorCamera {
    /// The camera's width and height in pixels.
    fn size(&self) -> (u32, u32);
    /// Code values per channel (256 for 8 bits).
    fn levels(&self) -> u32;
    /// The camera's usual exposure time (seconds), the bracket's middle.
    fn base_exposure_s(&self) -> f64;
    /// Show `crt` on the face and `spot` (or every projector black), and
    /// capture one frame per exposure time, row-major codes.
    fn capture(
        &mut self,
        crt: CrtPattern,
        spot: Option<Spot>,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>>;
    /// Show `lamp` on projector `projector` (device values, not through
    /// any profile), every other projector black and the CRT off, and
    /// capture one frame per exposure time, row-major codes.
    fn capture_projector(
        &mut self,
        projector: usize,
        lamp: Lamp,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        let _ = (projector, lamp, exposures_s);
        anyhow::bail!("this rig cannot switch a projector's lamp or show it uniform values")
    }
}

/// The simulated rig: the true face, projectors and camera.
pub struct SimMirrorCamera<'a> {
    frame: &'a FrameScene,
    face: &'a CrtFace,
    photometer: Photometer<'a>,
    /// The real part under each projector pattern met so far.
    real: Vec<(Option<Spot>, RgbImage)>,
    /// Per projector met so far: the real part with its lamp off (the
    /// others black), and its own light at 1 W/sr in every pixel.
    lamps: Vec<(usize, RgbImage, RgbImage)>,
}

impl<'a> SimMirrorCamera<'a> {
    /// `camera` (true device and response) through `face` (true CRT and
    /// splitter) in the true scene `frame`; real light path-traced with
    /// `options`.
    pub fn new(
        frame: &'a FrameScene,
        face: &'a CrtFace,
        camera: &'a Camera,
        options: CompleteOptions,
    ) -> Result<Self> {
        Ok(Self {
            frame,
            face,
            photometer: Photometer::new(frame, face, camera, options)?,
            real: Vec::new(),
            lamps: Vec::new(),
        })
    }

    fn real(&mut self, spot: Option<Spot>) -> Result<&RgbImage> {
        if let Some(i) = self.real.iter().position(|(s, _)| *s == spot) {
            return Ok(&self.real[i].1);
        }
        let projectors = &self.frame.showcase.projectors;
        if let Some(s) = spot {
            anyhow::ensure!(
                s.projector < projectors.len(),
                "spot on projector {} of {}",
                s.projector,
                projectors.len()
            );
        }
        let images: Vec<RgbImage> = projectors
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (w, h) = (p.device.width, p.device.height);
                match spot {
                    Some(s) if s.projector == i => s.image(w, h),
                    _ => Image::new(w, h, Vec3::ZERO),
                }
            })
            .collect();
        let projected: Vec<ProjectedLight<'_>> = projectors
            .iter()
            .zip(&images)
            .map(|(projector, value)| ProjectedLight { projector, value })
            .collect();
        let real = self
            .photometer
            .real(&projected)
            .context("simulating the real objects under the projectors")?;
        self.real.push((spot, real));
        Ok(&self.real.last().expect("just pushed").1)
    }
}

impl SimMirrorCamera<'_> {
    /// The real part with projector `p` showing `lamp`: light is linear in
    /// a projector's intensity, so the scene with its lamp off plus its
    /// true intensity at `lamp` times its light at 1 W/sr.
    fn lamp(&mut self, p: usize, lamp: Lamp) -> Result<RgbImage> {
        let projectors = &self.frame.showcase.projectors;
        let projector = projectors
            .get(p)
            .with_context(|| format!("no projector {p}: the scene has {}", projectors.len()))?;
        if !self.lamps.iter().any(|(i, _, _)| *i == p) {
            let black: Vec<RgbImage> = projectors
                .iter()
                .map(|q| Image::new(q.device.width, q.device.height, Vec3::ZERO))
                .collect();
            let others: Vec<ProjectedLight<'_>> = projectors
                .iter()
                .zip(&black)
                .enumerate()
                .filter(|(i, _)| *i != p)
                .map(|(_, (projector, value))| ProjectedLight { projector, value })
                .collect();
            let off = self
                .photometer
                .real(&others)
                .context("simulating the real objects with a projector's lamp off")?;
            let unit_projector = showcase_proto::Projector {
                response: showcase_proto::ProjectorResponse {
                    gamma: 1.0,
                    eta: 1.0,
                    black_level: 0.0,
                    wheel_segments: Vec::new(),
                    photometry: None,
                    ..projector.response.clone()
                },
                ..projector.clone()
            };
            let ones = Image::new(projector.device.width, projector.device.height, Vec3::ONE);
            let unit = self
                .photometer
                .real(&[ProjectedLight {
                    projector: &unit_projector,
                    value: &ones,
                }])
                .context("simulating the real objects under one projector")?;
            self.lamps.push((p, off, unit));
        }
        let (_, off, unit) = self
            .lamps
            .iter()
            .find(|(i, _, _)| *i == p)
            .context("just simulated")?;
        Ok(match lamp {
            Lamp::Off => off.clone(),
            Lamp::Uniform(v) => {
                let light = showcase_light::sim::devices::projector_intensity(
                    &projector.response,
                    Vec3::splat(v),
                );
                Image {
                    width: off.width,
                    height: off.height,
                    data: off
                        .data
                        .iter()
                        .zip(&unit.data)
                        .map(|(o, u)| *o + light * *u)
                        .collect(),
                }
            }
        })
    }
}

impl MirrorCamera for SimMirrorCamera<'_> {
    fn size(&self) -> (u32, u32) {
        let d = &self.photometer.camera().device;
        (d.width, d.height)
    }

    fn levels(&self) -> u32 {
        1 << self.photometer.camera().response.bits.clamp(1, 16)
    }

    fn base_exposure_s(&self) -> f64 {
        f64::from(self.photometer.camera().response.exposure_s)
    }

    fn capture(
        &mut self,
        crt: CrtPattern,
        spot: Option<Spot>,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        let real = self.real(spot)?.clone();
        let drive = crt.drive(self.face.width, self.face.height);
        let shows = drive.as_ref().map_or(CrtShows::Off, CrtShows::Drive);
        let radiance = self.photometer.radiance(&real, shows)?;
        Ok(self
            .photometer
            .capture(&radiance, exposures_s)
            .into_iter()
            .map(|f| f.codes.data)
            .collect())
    }

    fn capture_projector(
        &mut self,
        projector: usize,
        lamp: Lamp,
        exposures_s: &[f64],
    ) -> Result<Vec<Vec<[u16; 3]>>> {
        let real = self.lamp(projector, lamp)?;
        let radiance = self.photometer.radiance(&real, CrtShows::Off)?;
        Ok(self
            .photometer
            .capture(&radiance, exposures_s)
            .into_iter()
            .map(|f| f.codes.data)
            .collect())
    }
}
