//! The sim's projectors and cameras over one shared [`SimWorld`].
//!
//! # Projector
//! A point light at the projector's centre. Pixel value `v` (clamped to
//! `[0, 1]`) emits the radiant intensity `eta * v^gamma + black_level`
//! (W/sr, per channel) along the directions of that pixel, averaged over a
//! colour-wheel turn. With DLP time slicing the wheel has `n` equal
//! segments of RGB transmission `T_k`; while segment `k` is in front of the
//! lamp the intensity is `T_k / mean(T)` times the average, so a full turn
//! integrates to the average and a shorter exposure only to the segments it
//! overlaps ([`wheel_weights`]). The wheel starts at the sim's
//! `wheel_phase_s`, which the capturing side does not know.
//!
//! # Camera
//! The signal of a pixel is `gain * exposure * L` (1 = full scale) for the
//! radiance `L` it sees averaged over the exposure, plus Gaussian noise of
//! variance `shot_noise * signal + read_noise^2`, clamped to `[0, 1]`, put
//! through the response `signal^(1/gamma)` and quantised to `bits` bits.
//! Noise is seeded by `(seed, camera, capture number)`.
//!
//! Light transport is path traced once per shown projector image and
//! camera, and cached; captures then only apply the wheel and the camera.
//! A projector image whose brightest pixel emits a fraction `f` of the
//! projector's full-white intensity is traced with `ceil(f * spp)` paths
//! per pixel (at least 1): a projector showing black adds only its black
//! level, whose noise is small even with one path.

use super::quantiser::Quantiser;
use super::world::{ProjectorLight, SimWorld, TransportImage};
use super::{SimError, SimLights};
use crate::finite::{finite_or, finite_or_zero};
use crate::hardware::{CameraDevice, CameraFrame, ProjectorDevice};
use crate::sampling::pixel_seed;
use crate::{DeviceRays, Image, ObjectFilter, RgbImage};
use glam::{DVec3, Vec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use showcase_proto::{CameraResponse, PinholeDevice, ProjectorResponse, Showcase};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};

/// Settings of a simulated showcase.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Paths per camera pixel for the light transport of a projector
    /// showing full white (dimmer images get proportionally fewer, see the
    /// module docs).
    pub samples_per_pixel: u32,
    /// Seed of every random choice (transport and camera noise).
    pub seed: u64,
    /// Time (s) at which the colour wheel's first segment begins.
    pub wheel_phase_s: f64,
    /// Whether the scene's own emitters are on.
    pub emitters: bool,
    /// Which objects physically exist (default: the real ones).
    pub objects: ObjectFilter,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            samples_per_pixel: 64,
            seed: 1,
            wheel_phase_s: 0.0013,
            emitters: false,
            objects: ObjectFilter::Real,
        }
    }
}

struct Shared {
    world: SimWorld,
    projectors: Vec<showcase_proto::Projector>,
    cameras: Vec<showcase_proto::Camera>,
    config: SimConfig,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    /// Shown pixel values per projector (`None`: all black).
    shown: Vec<Option<RgbImage>>,
    /// Content hash of each projector's shown image.
    version: Vec<u64>,
    /// `(camera, projector, content hash) -> transport`.
    cache: HashMap<(usize, usize, u64), Arc<TransportImage>>,
    /// `camera -> emitter transport`.
    emitter_cache: HashMap<usize, Arc<RgbImage>>,
}

/// A simulated showcase: one world, its projectors and cameras.
#[derive(Clone)]
pub struct SimShowcase {
    shared: Arc<Shared>,
}

impl std::fmt::Debug for SimShowcase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimShowcase")
            .field("projectors", &self.shared.projectors.len())
            .field("cameras", &self.shared.cameras.len())
            .finish()
    }
}

impl SimShowcase {
    /// The physical showcase of `scene`: its objects accepted by
    /// `config.objects`, its projectors and cameras.
    pub fn new(scene: &Showcase, config: SimConfig) -> Result<Self, SimError> {
        let world = SimWorld::new(scene, &config.objects, config.emitters)?;
        for p in &scene.projectors {
            DeviceRays::new(&p.device)?;
        }
        for c in &scene.cameras {
            DeviceRays::new(&c.device)?;
        }
        let state = State {
            shown: vec![None; scene.projectors.len()],
            version: vec![0; scene.projectors.len()],
            ..State::default()
        };
        Ok(Self {
            shared: Arc::new(Shared {
                world,
                projectors: scene.projectors.clone(),
                cameras: scene.cameras.clone(),
                config,
                state: Mutex::new(state),
            }),
        })
    }

    /// The world.
    pub fn world(&self) -> &SimWorld {
        &self.shared.world
    }

    /// Projector `index` as a device.
    pub fn projector(&self, index: usize) -> Result<SimProjector, SimError> {
        if index >= self.shared.projectors.len() {
            return Err(SimError::NoDevice {
                what: "projector",
                index,
            });
        }
        Ok(SimProjector {
            shared: self.shared.clone(),
            index,
        })
    }

    /// Camera `index` as a device.
    pub fn camera(&self, index: usize) -> Result<SimCamera, SimError> {
        if index >= self.shared.cameras.len() {
            return Err(SimError::NoDevice {
                what: "camera",
                index,
            });
        }
        let response = self.shared.cameras[index].response.clone();
        Ok(SimCamera {
            quantiser: Arc::new(Quantiser::new(&response)),
            response,
            shared: self.shared.clone(),
            index,
            captures: 0,
        })
    }

    /// Ground truth: the true albedo each pixel of camera `camera` sees,
    /// and its object index.
    pub fn ground_truth(&self, camera: usize) -> Result<(RgbImage, Image<Option<u32>>), SimError> {
        let c = self.shared.cameras.get(camera).ok_or(SimError::NoDevice {
            what: "camera",
            index: camera,
        })?;
        Ok(self.shared.world.ground_truth(&DeviceRays::new(&c.device)?))
    }

    /// Ground truth: the radiance camera `camera` sees from projector
    /// `projector`'s current image, averaged over whole wheel turns, split
    /// into direct and indirect light.
    pub fn transport(&self, camera: usize, projector: usize) -> Result<TransportImage, SimError> {
        Ok((*self.shared.transport(camera, projector)?).clone())
    }
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn transport(&self, camera: usize, projector: usize) -> Result<Arc<TransportImage>, SimError> {
        let cam = self.cameras.get(camera).ok_or(SimError::NoDevice {
            what: "camera",
            index: camera,
        })?;
        let proj = self.projectors.get(projector).ok_or(SimError::NoDevice {
            what: "projector",
            index: projector,
        })?;
        let mut state = self.lock();
        let version = state.version[projector];
        if let Some(t) = state.cache.get(&(camera, projector, version)) {
            return Ok(t.clone());
        }
        let rays = DeviceRays::new(&proj.device)?;
        let (w, h) = (proj.device.width, proj.device.height);
        let intensity = match &state.shown[projector] {
            Some(img) => img.map(|v| projector_intensity(&proj.response, *v)),
            None => Image::new(w, h, projector_intensity(&proj.response, Vec3::ZERO)),
        };
        // A projector that shows only a fraction of its full-white light
        // (black, or a dim image) adds little, so its noise stays small
        // with proportionally fewer paths.
        let peak = |img: &RgbImage| {
            img.data
                .iter()
                .map(|v| v.max_element() as f64)
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
        };
        let full = projector_intensity(&proj.response, Vec3::ONE).max_element() as f64;
        let fraction = if full > 0.0 {
            (peak(&intensity) / full).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let samples = ((self.config.samples_per_pixel as f64 * fraction).ceil() as u32)
            .clamp(1, self.config.samples_per_pixel.max(1));
        let light = ProjectorLight::new(rays, intensity)?;
        let seed = pixel_seed(
            self.config.seed,
            ((camera as u64) << 40) ^ ((projector as u64) << 20),
        );
        let t = Arc::new(self.world.render(
            &DeviceRays::new(&cam.device)?,
            &SimLights::projectors([&light]),
            samples,
            seed,
        ));
        state.cache.insert((camera, projector, version), t.clone());
        Ok(t)
    }

    fn emitted(&self, camera: usize) -> Result<Arc<RgbImage>, SimError> {
        let cam = &self.cameras[camera];
        let mut state = self.lock();
        if let Some(e) = state.emitter_cache.get(&camera) {
            return Ok(e.clone());
        }
        let e = Arc::new(if self.world.emitter_count() == 0 {
            Image::new(cam.device.width, cam.device.height, Vec3::ZERO)
        } else {
            let seed = pixel_seed(self.config.seed ^ 0x00E1_7717, camera as u64);
            self.world
                .render(
                    &DeviceRays::new(&cam.device)?,
                    &SimLights::none(),
                    self.config.samples_per_pixel,
                    seed,
                )
                .total()
        });
        state.emitter_cache.insert(camera, e.clone());
        Ok(e)
    }
}

/// Average radiant intensity (W/sr) of a projector pixel of value `value`:
/// the device's own per-channel curve where the scene states one
/// ([`ProjectorResponse::photometry`], the simulated showcase's truth),
/// else `eta * clamp(value, 0, 1)^gamma + black_level` per channel.
pub fn projector_intensity(response: &ProjectorResponse, value: Vec3) -> Vec3 {
    if response.photometry.is_some() {
        let out = response.light(value);
        return if out.is_finite() {
            out.max(Vec3::ZERO)
        } else {
            Vec3::ZERO
        };
    }
    let v = DVec3::from(value.to_array().map(|c| {
        let c = finite_or_zero(c).clamp(0.0, 1.0);
        c as f64
    }));
    let gamma = if response.gamma.is_finite() && response.gamma > 0.0 {
        response.gamma as f64
    } else {
        1.0
    };
    let out = DVec3::new(v.x.powf(gamma), v.y.powf(gamma), v.z.powf(gamma)) * response.eta as f64
        + DVec3::splat(response.black_level as f64);
    finite_or_zero(out).max(DVec3::ZERO).as_vec3()
}

/// Per-channel factor by which the colour wheel scales a projector's
/// average light over the exposure `[start_s, start_s + exposure_s]`, for a
/// wheel whose first segment begins at `phase_s`. 1 for a full turn (or a
/// projector without segments); for an exposure of zero length, the
/// factor of the segment in front of the lamp at `start_s`.
pub fn wheel_weights(
    response: &ProjectorResponse,
    phase_s: f64,
    start_s: f64,
    exposure_s: f64,
) -> DVec3 {
    let segments = &response.wheel_segments;
    let period = response.wheel_period_s as f64;
    if segments.is_empty() || !(period > 0.0 && period.is_finite()) {
        return DVec3::ONE;
    }
    let t: Vec<DVec3> = segments
        .iter()
        .map(|s| finite_or_zero(*s).as_dvec3().max(DVec3::ZERO))
        .collect();
    let n = t.len() as f64;
    let mean = t.iter().copied().sum::<DVec3>() / n;
    let seg = period / n;
    // Integral of T from the wheel's start to time `x`.
    let integral = |x: f64| {
        let local = x - phase_s;
        let turns = (local / period).floor();
        let mut rem = local - turns * period;
        let mut acc = mean * n * seg * turns;
        for s in &t {
            let d = rem.min(seg).max(0.0);
            acc += *s * d;
            rem -= d;
        }
        acc
    };
    let ratio = |num: DVec3| {
        DVec3::from(std::array::from_fn::<f64, 3, _>(|c| {
            if mean[c] > 0.0 { num[c] / mean[c] } else { 0.0 }
        }))
    };
    let w = if exposure_s > 0.0 {
        ratio((integral(start_s + exposure_s) - integral(start_s)) / exposure_s)
    } else {
        let local = (start_s - phase_s).rem_euclid(period);
        let k = ((local / seg) as usize).min(t.len() - 1);
        ratio(t[k])
    };
    finite_or(w, DVec3::ONE)
}

/// A simulated projector (see the module docs).
#[derive(Clone)]
pub struct SimProjector {
    shared: Arc<Shared>,
    index: usize,
}

impl std::fmt::Debug for SimProjector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SimProjector({})", self.index)
    }
}

impl ProjectorDevice for SimProjector {
    type Error = SimError;

    fn device(&self) -> &PinholeDevice {
        &self.shared.projectors[self.index].device
    }

    fn show(&mut self, image: &RgbImage) -> Result<(), SimError> {
        let d = self.device();
        if image.width != d.width || image.height != d.height {
            return Err(SimError::ImageSize {
                expected: (d.width, d.height),
                got: (image.width, image.height),
            });
        }
        let clamped =
            image.map(|v| Vec3::from(v.to_array().map(|c| finite_or_zero(c).clamp(0.0, 1.0))));
        let hash = content_hash(&clamped);
        let mut state = self.shared.lock();
        state.shown[self.index] = Some(clamped);
        state.version[self.index] = hash;
        Ok(())
    }

    fn wheel_period_s(&self) -> f64 {
        let r = &self.shared.projectors[self.index].response;
        if r.wheel_segments.is_empty() {
            0.0
        } else {
            r.wheel_period_s as f64
        }
    }
}

/// A simulated camera (see the module docs).
#[derive(Clone)]
pub struct SimCamera {
    shared: Arc<Shared>,
    index: usize,
    captures: u64,
    /// The camera's response, its gain as last fixed.
    response: CameraResponse,
    /// Its quantisation (the gain does not change it).
    quantiser: Arc<Quantiser>,
}

impl SimCamera {
    /// Fix the gain (as an operator sets a camera's gain by hand: no
    /// automatic gain, exposure or white balance).
    pub fn set_gain(&mut self, gain: f32) {
        self.response.gain = gain;
    }

    /// Fix the exposure the response reports.
    pub fn set_exposure(&mut self, exposure_s: f32) {
        self.response.exposure_s = exposure_s;
    }
}

impl std::fmt::Debug for SimCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SimCamera({})", self.index)
    }
}

impl CameraDevice for SimCamera {
    type Error = SimError;

    fn device(&self) -> &PinholeDevice {
        &self.shared.cameras[self.index].device
    }

    fn response(&self) -> &CameraResponse {
        &self.response
    }

    fn capture(&mut self, start_s: f64, exposure_s: f64) -> Result<CameraFrame, SimError> {
        if !(start_s.is_finite() && exposure_s.is_finite() && exposure_s >= 0.0) {
            return Err(SimError::BadExposure {
                start_s,
                duration_s: exposure_s,
            });
        }
        let shared = &self.shared;
        let mut radiance: Vec<DVec3> = shared
            .emitted(self.index)?
            .data
            .iter()
            .map(|v| v.as_dvec3())
            .collect();
        for p in 0..shared.projectors.len() {
            let t = shared.transport(self.index, p)?;
            let w = wheel_weights(
                &shared.projectors[p].response,
                shared.config.wheel_phase_s,
                start_s,
                exposure_s,
            );
            for (i, l) in radiance.iter_mut().enumerate() {
                *l += w * (t.direct.data[i] + t.indirect.data[i]).as_dvec3();
            }
        }
        let seed = pixel_seed(
            shared.config.seed ^ 0x0CA3_E7A0,
            ((self.index as u64) << 32) ^ self.captures,
        );
        self.captures += 1;
        let codes = expose(
            self.response(),
            &self.quantiser,
            &radiance,
            exposure_s,
            seed,
        );
        let d = self.device();
        Ok(CameraFrame {
            codes: Image {
                width: d.width,
                height: d.height,
                data: codes,
            },
            bits: self.response().bits.clamp(1, 16),
        })
    }
}

/// A camera's codes for `radiance` (per pixel) exposed for `exposure_s`:
/// signal `gain * exposure * radiance`, shot and read noise from the
/// stream `seed`, clipped to full scale, the response curve
/// ([`CameraResponse::encode`]) and quantisation to `bits`, through
/// `quantiser` when it is `response`'s (else one made for it).
pub fn expose(
    response: &CameraResponse,
    quantiser: &Quantiser,
    radiance: &[DVec3],
    exposure_s: f64,
    seed: u64,
) -> Vec<[u16; 3]> {
    let made;
    let quantiser = if quantiser.matches(response) {
        quantiser
    } else {
        made = Quantiser::new(response);
        &made
    };
    let gain = finite_or(response.gain as f64, 0.0) * finite_or(exposure_s, 0.0);
    let read = finite_or(response.read_noise as f64, 0.0).max(0.0);
    let shot = finite_or(response.shot_noise as f64, 0.0).max(0.0);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    radiance
        .iter()
        .map(|l| {
            std::array::from_fn(|c| {
                let s = gain * l[c];
                let sd = (shot * s.max(0.0) + read * read).sqrt();
                let z: f64 = StandardNormal.sample(&mut rng);
                let s = finite_or(s + sd * z, 0.0).clamp(0.0, 1.0);
                quantiser.code(c, s)
            })
        })
        .collect()
}

/// A hash of an image's pixel values (the transport cache key).
fn content_hash(image: &RgbImage) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (image.width, image.height).hash(&mut h);
    for v in &image.data {
        v.to_array().map(f32::to_bits).hash(&mut h);
    }
    h.finish()
}
