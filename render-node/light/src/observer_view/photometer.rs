//! A camera in an observer's place, looking through a face's beam
//! splitter: the tripod camera of photometric calibration, simulated.
//!
//! What reaches it is what reaches an eye there ([`super::observer_view`]):
//! the real objects under the projectors, every bounce (the complete
//! view's real part, [`complete_real`]), through the splitter's
//! transmission, plus the CRT's light for the drive values it shows, from
//! its true response, by the splitter's reflection. Each camera pixel
//! averages the same `SUBSAMPLES x SUBSAMPLES` rays as the eye's pixels
//! do. The camera then exposes it with its true response, noise and
//! quantisation ([`crate::sim::devices::expose`]), a fresh noise stream
//! per frame.
//!
//! The calibration that uses it never sees the truth: only frames.

use super::complete::{CompleteOptions, complete_real};
use super::{ObserverViewError, ProjectedLight, SUBSAMPLES, check_size, mirror_pixel};
use crate::hardware::CameraFrame;
use crate::render::{FrameScene, RenderSetupError};
use crate::sampling::pixel_seed;
use crate::sim::devices::expose;
use crate::sim::quantiser::Quantiser;
use crate::{DeviceRays, Image, RgbImage};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;
use showcase_proto::{Camera, CrtFace};

/// What the CRT shows.
#[derive(Clone, Copy, Debug)]
pub enum CrtShows<'a> {
    /// Switched off: no light at all (not even its black level).
    Off,
    /// These drive values, face-sized.
    Drive(&'a RgbImage),
}

/// The simulated tripod camera (see the module docs).
#[derive(Debug)]
pub struct Photometer<'a> {
    frame: &'a FrameScene,
    face: &'a CrtFace,
    camera: &'a Camera,
    options: CompleteOptions,
    /// Per camera pixel, the CRT pixel each subsample ray sees by way of
    /// the mirror (row-major index), if any.
    mirror: Vec<Vec<usize>>,
    /// The camera's quantisation.
    quantiser: Quantiser,
    frames: u64,
}

impl<'a> Photometer<'a> {
    /// `camera` (its true device and response) looking at the true scene
    /// `frame` through `face` (its true CRT and splitter); the real part
    /// is path-traced with `options`.
    pub fn new(
        frame: &'a FrameScene,
        face: &'a CrtFace,
        camera: &'a Camera,
        options: CompleteOptions,
    ) -> Result<Self, ObserverViewError> {
        let rays = DeviceRays::new(&camera.device).map_err(RenderSetupError::from)?;
        let d = &camera.device;
        let mirror = (0..d.width * d.height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % d.width, i / d.width);
                (0..SUBSAMPLES * SUBSAMPLES)
                    .filter_map(|k| {
                        let offset = DVec2::new(
                            ((k % SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                            ((k / SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                        );
                        let ray = rays.ray_through(DVec2::new(x as f64, y as f64) + offset)?;
                        let p = mirror_pixel(face, &ray)?;
                        let (px, py) = (p.x as u32, p.y as u32);
                        (px < face.width && py < face.height)
                            .then_some((py * face.width + px) as usize)
                    })
                    .collect()
            })
            .collect();
        Ok(Self {
            frame,
            face,
            camera,
            options,
            mirror,
            quantiser: Quantiser::new(&camera.response),
            frames: 0,
        })
    }

    /// The camera (its true device and response).
    pub fn camera(&self) -> &Camera {
        self.camera
    }

    /// The real objects' radiance at the camera under `projected`, every
    /// bounce, before the splitter (the part to keep while only the CRT
    /// changes).
    pub fn real(&self, projected: &[ProjectedLight<'_>]) -> Result<RgbImage, ObserverViewError> {
        Ok(complete_real(self.frame, &self.camera.device, projected, self.options)?.radiance)
    }

    /// The light reaching the camera: `real` ([`Self::real`]) through the
    /// splitter's transmission plus the CRT's light for `crt` by its
    /// reflection.
    pub fn radiance(
        &self,
        real: &RgbImage,
        crt: CrtShows<'_>,
    ) -> Result<RgbImage, ObserverViewError> {
        let d = &self.camera.device;
        check_size("the real part", real, d.width, d.height)?;
        if let CrtShows::Drive(drive) = crt {
            check_size(&self.face.name, drive, self.face.width, self.face.height)?;
        }
        let glass = self.face.photometry.splitter;
        let n = f64::from(SUBSAMPLES * SUBSAMPLES);
        let data = real
            .data
            .par_iter()
            .zip(&self.mirror)
            .map(|(real, seen)| {
                let crt = match crt {
                    CrtShows::Off => DVec3::ZERO,
                    CrtShows::Drive(drive) => {
                        seen.iter()
                            .map(|&p| self.face.photometry.crt.emit(drive.data[p]).as_dvec3())
                            .sum::<DVec3>()
                            / n
                    }
                };
                glass.transmission * *real + glass.reflection * crt.as_vec3()
            })
            .collect::<Vec<Vec3>>();
        Ok(Image {
            width: d.width,
            height: d.height,
            data,
        })
    }

    /// Pixels that see some of the CRT's screen by way of the mirror, with
    /// every subsample ray on it.
    pub fn sees_screen(&self) -> Image<bool> {
        let d = &self.camera.device;
        let all = (SUBSAMPLES * SUBSAMPLES) as usize;
        Image {
            width: d.width,
            height: d.height,
            data: self.mirror.iter().map(|s| s.len() == all).collect(),
        }
    }

    /// One frame of `radiance` per exposure time in `exposures_s`, each
    /// with a fresh noise stream (the frames are made in parallel; each
    /// stream is keyed by the frame's number alone).
    pub fn capture(&mut self, radiance: &RgbImage, exposures_s: &[f64]) -> Vec<CameraFrame> {
        let first = self.frames;
        self.frames += exposures_s.len() as u64;
        let linear: Vec<DVec3> = radiance.data.iter().map(|v| v.as_dvec3()).collect();
        let (response, quantiser) = (&self.camera.response, &self.quantiser);
        let seed = self.options.seed ^ 0x7E1F_0A2D;
        exposures_s
            .par_iter()
            .enumerate()
            .map(|(j, t)| CameraFrame {
                codes: Image {
                    width: radiance.width,
                    height: radiance.height,
                    data: expose(
                        response,
                        quantiser,
                        &linear,
                        *t,
                        pixel_seed(seed, first + j as u64),
                    ),
                },
                bits: response.bits.clamp(1, 16),
            })
            .collect()
    }
}
