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
}

/// The simulated rig: the true face, projectors and camera.
pub struct SimMirrorCamera<'a> {
    frame: &'a FrameScene,
    face: &'a CrtFace,
    photometer: Photometer<'a>,
    /// The real part under each projector pattern met so far.
    real: Vec<(Option<Spot>, RgbImage)>,
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
}
