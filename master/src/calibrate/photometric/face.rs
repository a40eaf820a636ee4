//! Photometric calibration of a CRT face through its beam splitter, with
//! a camera in an observer's place ([`MirrorCamera`]):
//!
//! 1. **Camera response** from an exposure bracket of the CRT showing a
//!    ramp ([`super::response`], Debevec-Malik); every later measurement is
//!    an HDR merge of a bracket through it, so it is linear up to one scale
//!    per channel.
//! 2. **A reference of known radiance**: a square of one projector's pixels
//!    on a real surface the camera sees, whose radiance the product
//!    predicts from what it knows (the projector's calibrated device and
//!    response, the surface's reflectance): `rho / pi * dI * cos / d^2`.
//!    The camera sees it through the splitter's transmission, so the ratio
//!    of measured to predicted is the camera's scale times `T`, per
//!    channel.
//! 3. **The CRT's light through the mirror** at a ladder of grey drive
//!    levels, each camera channel measuring its CRT channel (the profile
//!    is per channel, without crosstalk), less the frame with the CRT
//!    switched off, over the pixels that see the screen: the camera's
//!    scale times `R * emit(d)`.
//! 4. Their quotient is what the face adds, in the units of the real
//!    surfaces behind the glass: `R / T * emit(d)`, which
//!    [`CrtPhotometry::seen`] models. A power curve with a black level is
//!    fitted per channel; the profile carries it with an ideal splitter
//!    (only the ratio matters to a node).
//! 5. **Held-out levels** between the fitted ones judge the new profile
//!    against the one in place; the new one is kept only if it is no
//!    worse.
//!
//! Checks that stop the calibration with what to do: a patch saturated or
//! under-exposed at every exposure of the bracket, a CRT whose measured
//! light falls as its drive rises, a camera that moved between the first
//! and the last frames, a reference spot the camera cannot see.

use super::response::{ExposureBracket, RecoveredResponse, ResponseOptions, recover_response};
use super::rig::{CrtPattern, MirrorCamera, Spot};
use anyhow::{Context, Result, bail};
use glam::{DVec2, DVec3, Vec3};
use serde::Serialize;
use showcase_light::render::projector::device_intensity;
use showcase_light::{DeviceRays, ObjectFilter, SceneGeometry, metrics};
use showcase_proto::{BeamSplitter, CrtFace, CrtPhotometry, CrtResponse, PinholeDevice, Showcase};

/// How the calibration measures.
#[derive(Clone, Debug)]
pub struct PhotometricOptions {
    /// The bracket: exposure times are the camera's base exposure times
    /// `2^stop`.
    pub stops: Vec<i32>,
    /// Drive levels fitted per channel above 0: `k / levels`, `k` in
    /// `1..=levels`.
    pub levels: u32,
    /// Held-out levels per channel, between the fitted ones: `(k + 0.5) /
    /// levels` for these `k`.
    pub held_out: Vec<u32>,
    /// Half the side of the reference spot, in projector pixels.
    pub spot_half: u32,
    /// Frames per exposure, combined by their median code (the camera's
    /// read noise falls about as its square root).
    pub frames_per_exposure: u32,
    /// Pixel sites of the ramp the camera's response is recovered from.
    pub response_samples: usize,
}

impl Default for PhotometricOptions {
    fn default() -> Self {
        Self {
            // Up to 512 times the base exposure: the ramp's dim end and
            // the CRT's lowest levels rise well above the read noise.
            stops: (-3..=9).collect(),
            levels: 12,
            held_out: vec![1, 4, 7, 10],
            spot_half: 10,
            frames_per_exposure: 16,
            response_samples: 4000,
        }
    }
}

/// The reference spot and the radiance the product predicts for it.
#[derive(Clone, Debug, Serialize)]
pub struct Reference {
    /// Which projector shows it (by name).
    pub projector: String,
    /// The spot.
    #[serde(skip)]
    pub spot: Spot,
    /// The surface point at its centre (world metres).
    pub point: [f64; 3],
    /// Radiance the spot adds there (W/m^2/sr), predicted: the median
    /// over the pixels compared.
    pub radiance: [f64; 3],
    /// What the camera measured of it (its linear units), the median.
    pub measured: [f64; 3],
    /// The camera's scale per channel: the median of measured over
    /// predicted, pixel by pixel.
    pub scale: [f64; 3],
    /// Camera pixels compared: those the spot lights wholly.
    pub pixels: usize,
}

/// One drive level's measurement in one channel.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Level {
    /// The channel.
    pub channel: usize,
    /// The drive value.
    pub drive: f64,
    /// What the CRT adds, in the units of radiance behind the glass.
    pub seen: f64,
    /// Held out of the fit.
    pub held_out: bool,
}

/// A face's photometric calibration.
#[derive(Clone, Debug, Serialize)]
pub struct FaceCalibration {
    /// The face.
    pub face: String,
    /// The profile to use: the new one, or the one in place when the new
    /// one is worse on the held-out levels.
    pub profile: CrtPhotometry,
    /// The profile fitted from this run.
    pub fitted: CrtPhotometry,
    /// The new profile was worse than the one in place, so that is kept.
    pub kept_previous: bool,
    /// Largest relative error on the held-out levels: of the fitted
    /// profile, and of the one in place.
    pub held_out_error: f64,
    /// [`Self::held_out_error`] of the profile in place.
    pub held_out_error_before: f64,
    /// The reference.
    pub reference: Reference,
    /// Every level measured.
    pub levels: Vec<Level>,
    /// The recovered camera response.
    #[serde(skip)]
    pub response: RecoveredResponse,
    /// Camera pixels that see the screen (the CRT measurements' region).
    pub screen_pixels: usize,
    /// The camera's noise floor (code), from the dark frame.
    pub noise_floor: u32,
    /// Frames captured.
    pub frames: usize,
}

/// Calibrate `face` of the product's `scene` (its calibrated devices and
/// the real surfaces' reflectance) with `rig`, a camera at `camera` (its
/// pose, as calibrated); `previous` is the profile in place.
pub fn calibrate_face(
    rig: &mut dyn MirrorCamera,
    scene: &Showcase,
    face: &CrtFace,
    camera: &PinholeDevice,
    previous: &CrtPhotometry,
    options: &PhotometricOptions,
) -> Result<FaceCalibration> {
    let (w, h) = rig.size();
    anyhow::ensure!(
        (w, h) == (camera.width, camera.height),
        "the rig's camera is {w}x{h} but its calibrated device is {}x{}",
        camera.width,
        camera.height
    );
    let base = rig.base_exposure_s();
    anyhow::ensure!(
        base.is_finite() && base > 0.0,
        "the camera's exposure time {base} s is not a positive time"
    );
    let exposures: Vec<f64> = options.stops.iter().map(|s| base * 2f64.powi(*s)).collect();
    let k = options.frames_per_exposure.max(1) as usize;
    let repeated: Vec<f64> = exposures
        .iter()
        .flat_map(|t| std::iter::repeat_n(*t, k))
        .collect();
    let mut frames = 0;
    let mut shoot = |rig: &mut dyn MirrorCamera,
                     crt: CrtPattern,
                     spot: Option<Spot>|
     -> Result<Vec<Vec<[u16; 3]>>> {
        frames += repeated.len();
        let shot = rig.capture(crt, spot, &repeated)?;
        anyhow::ensure!(
            shot.len() == repeated.len() && shot.iter().all(|f| f.len() == (w * h) as usize),
            "the camera returned {} frames for {} exposures, or frames of another size than \
             {w}x{h}",
            shot.len(),
            repeated.len()
        );
        Ok(shot.chunks(k).map(median_codes).collect())
    };

    let screen = screen_pixels(face, camera)?;
    anyhow::ensure!(
        screen.len() >= 16,
        "the camera sees only {} pixels of {}'s screen through its mirror: put it where an \
         observer of that face stands, facing the mirror",
        screen.len(),
        face.name
    );
    // The camera's noise floor: what it reads of the dark room (the CRT
    // off, the projectors black) at the shortest exposure, where hardly
    // any light reaches it; codes up to it are noise, not response.
    let dark = shoot(rig, CrtPattern::Off, None)?;
    let shortest = exposures
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let dark_codes: Vec<f64> = screen
        .iter()
        .flat_map(|&i| dark[shortest][i].map(f64::from))
        .collect();
    let noise_floor = metrics::percentile(&dark_codes, 99.0).unwrap_or(0.0) as u32 + 1;
    // 1. The camera's response, from the ramp, over the pixels that see
    // it (elsewhere the dark room is the camera's noise floor at every
    // exposure, which no response explains).
    let ramp = shoot(rig, CrtPattern::Ramp, None)?;
    let on_screen: Vec<Vec<[u16; 3]>> = ramp
        .iter()
        .map(|f| screen.iter().map(|&i| f[i]).collect())
        .collect();
    let bracket = ExposureBracket {
        exposures_s: &exposures,
        frames: &on_screen,
        levels: rig.levels(),
    };
    // A noisy camera's low codes leave a residual of about 0.1 in ln
    // exposure on a static scene (1 % read noise before a gamma of 2: at
    // code 30 the noise is a third of the signal even over 16 frames), so
    // the residual is not the test of a moved scene here: the ramp's first
    // and last frames are ([`check_still`]).
    let response_options = ResponseOptions {
        max_residual: 0.3,
        noise_floor,
        samples: options.response_samples,
        ..ResponseOptions::default()
    };
    let response = recover_response(&bracket, &response_options)
        .context("recovering the camera's response from the bracket of the CRT's ramp")?;
    let merge = Merge {
        response: &response,
        exposures: &exposures,
    };
    let ramp_before = merge.image(&ramp);
    let off = merge.image(&dark);

    // 2. The reference.
    let real = SceneGeometry::build(scene, &ObjectFilter::Real)?;
    let (spot, point) = choose_reference(&real, scene, camera, options.spot_half)?;
    let lit = merge.image(&shoot(rig, CrtPattern::Off, Some(spot))?);
    let (scale, measured, predicted, plateau) = spot_scale(&lit, &off, &real, scene, camera, spot)
        .with_context(|| format!("measuring the reference spot at {point:.3}"))?;

    // 3. The CRT's light, per channel and level.
    let mut levels = Vec::new();
    let mut drives: Vec<(f64, bool)> = vec![(0.0, false)];
    drives.extend((1..=options.levels).map(|k| (f64::from(k) / f64::from(options.levels), false)));
    drives.extend(
        options
            .held_out
            .iter()
            .filter(|k| **k < options.levels)
            .map(|k| ((f64::from(*k) + 0.5) / f64::from(options.levels), true)),
    );
    for &(d, held_out) in &drives {
        let img = merge.image(&shoot(
            rig,
            CrtPattern::Uniform(Vec3::splat(d as f32)),
            None,
        )?);
        for (c, channel) in CHANNELS.iter().enumerate() {
            let what = format!("the CRT at drive {d:.3} in channel {channel}");
            let value = region_median(&img, &off, &screen, c, &what)?;
            levels.push(Level {
                channel: c,
                drive: d,
                seen: value / scale[c],
                held_out,
            });
        }
    }
    // The ramp again: the camera must not have moved.
    let ramp_after = merge.image(&shoot(rig, CrtPattern::Ramp, None)?);
    check_still(&ramp_before, &ramp_after, &screen)?;

    // 4. The fit.
    let mut crt = CrtResponse::nominal(1.0);
    for (c, channel) in CHANNELS.iter().enumerate() {
        let mut fitted: Vec<(f64, f64)> = levels
            .iter()
            .filter(|l| l.channel == c && !l.held_out)
            .map(|l| (l.drive, l.seen))
            .collect();
        fitted.sort_by(|a, b| a.0.total_cmp(&b.0));
        check_monotonic(&fitted, c)?;
        let (gamma, peak, black) = fit_power(&fitted)
            .with_context(|| format!("fitting the CRT's curve in channel {channel}"))?;
        crt.gamma[c] = gamma as f32;
        crt.peak[c] = peak as f32;
        crt.black_level[c] = black as f32;
    }
    let fitted = CrtPhotometry {
        crt,
        splitter: BeamSplitter::IDEAL,
    };

    // 5. Held out: the new profile against the one in place.
    let held_out_error_before = held_out_error(previous, &levels);
    let held_out_error = held_out_error(&fitted, &levels);
    let kept_previous = held_out_error > held_out_error_before;
    Ok(FaceCalibration {
        face: face.name.clone(),
        profile: if kept_previous { *previous } else { fitted },
        fitted,
        kept_previous,
        held_out_error,
        held_out_error_before,
        reference: Reference {
            projector: scene
                .projectors
                .get(spot.projector)
                .map_or_else(String::new, |p| p.name.clone()),
            spot,
            point: point.to_array(),
            radiance: predicted,
            measured,
            scale,
            pixels: plateau,
        },
        levels,
        response,
        screen_pixels: screen.len(),
        noise_floor,
        frames,
    })
}

pub(super) const CHANNELS: [&str; 3] = ["red", "green", "blue"];

/// Frames of one exposure combined per pixel and channel: the median
/// code. A median commutes with the response (a monotonic curve), so the
/// median code is the response of the median signal, the noise-free one;
/// a mean of codes would carry the curve's bend into it (Jensen: about
/// 1 % of signal at 5 % of full scale under 1 % read noise, before a
/// gamma of 2).
pub(super) fn median_codes(frames: &[Vec<[u16; 3]>]) -> Vec<[u16; 3]> {
    let len = frames.first().map_or(0, Vec::len);
    let mut column = Vec::with_capacity(frames.len());
    (0..len)
        .map(|i| {
            std::array::from_fn(|c| {
                column.clear();
                column.extend(frames.iter().map(|f| f[i][c]));
                column.sort_unstable();
                let n = column.len();
                if n == 0 {
                    0
                } else if n % 2 == 1 {
                    column[n / 2]
                } else {
                    (u32::from(column[n / 2 - 1]) + u32::from(column[n / 2])).div_ceil(2) as u16
                }
            })
        })
        .collect()
}

/// The band of the code range measurements are read from ([`Merge::band`]).
const BAND: (f64, f64) = (0.3, 0.75);

/// HDR merge of a bracket through the recovered response.
pub(super) struct Merge<'a> {
    pub(super) response: &'a RecoveredResponse,
    pub(super) exposures: &'a [f64],
}

impl Merge<'_> {
    /// The codes a measurement is read from: the trusted codes within
    /// [`BAND`] of the range. A bracket in steps of 2 has at least one
    /// exposure in it for any light (2^(1/gamma) < 0.75 / 0.3), and every
    /// measurement read from the same band of the curve shares its error
    /// there, so ratios of measurements (the CRT's light to the reference
    /// spot's) hardly see it.
    fn band(&self, channel: usize) -> (u32, u32) {
        let (lo, hi) = self.response.trusted_range(channel);
        let max = f64::from(self.response.levels() - 1);
        let (a, b) = ((BAND.0 * max) as u32, (BAND.1 * max) as u32);
        (lo.max(a), hi.min(b))
    }

    /// Per pixel and channel, the weighted mean of the radiance each frame
    /// gives, hat weights over the [`Self::band`] (over all the trusted
    /// codes where no frame falls in it); 0 where every frame reads at or
    /// below the trusted codes (less light than the camera can tell from
    /// none, even at the longest exposure), NaN where none has a trusted
    /// code otherwise (saturated even at the shortest).
    pub(super) fn image(&self, frames: &[Vec<[u16; 3]>]) -> Vec<[f64; 3]> {
        let n = frames.first().map_or(0, Vec::len);
        let mean = |i: usize, c: usize, (lo, hi): (u32, u32)| {
            let half = f64::from(hi.saturating_sub(lo)).max(2.0) / 2.0;
            let (mut sum, mut weight) = (0.0, 0.0);
            for (frame, t) in frames.iter().zip(self.exposures) {
                let z = u32::from(frame[i][c]);
                if z <= lo || z >= hi {
                    continue;
                }
                let w = f64::from((z - lo).min(hi - z)) / half;
                sum += w * self.response.radiance(c, f64::from(z), *t);
                weight += w;
            }
            (weight > 0.0).then(|| sum / weight)
        };
        (0..n)
            .map(|i| {
                std::array::from_fn(|c| {
                    let trusted = self.response.trusted_range(c);
                    if let Some(v) = mean(i, c, self.band(c)).or_else(|| mean(i, c, trusted)) {
                        return v;
                    }
                    let dark = frames.iter().all(|f| u32::from(f[i][c]) <= trusted.0);
                    if dark { 0.0 } else { f64::NAN }
                })
            })
            .collect()
    }
}

/// Camera pixels whose every subsample ray sees `face`'s screen by way of
/// its mirror at least 4 screen pixels inside its edge (row-major
/// indices).
fn screen_pixels(face: &CrtFace, camera: &PinholeDevice) -> Result<Vec<usize>> {
    use showcase_light::observer_view::mirror_pixel;
    let rays = DeviceRays::new(camera)?;
    let margin = 4.0;
    let (fw, fh) = (f64::from(face.width), f64::from(face.height));
    let inside = |p: DVec2| p.x > margin && p.y > margin && p.x < fw - margin && p.y < fh - margin;
    Ok((0..camera.width * camera.height)
        .filter(|i| {
            let (x, y) = (i % camera.width, i / camera.width);
            [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
                .iter()
                .all(|(dx, dy)| {
                    rays.ray_through(DVec2::new(f64::from(x) + dx, f64::from(y) + dy))
                        .and_then(|r| mirror_pixel(face, &r))
                        .is_some_and(inside)
                })
        })
        .map(|i| i as usize)
        .collect())
}

/// The median over `region` of `img - off` in `channel`; an error naming
/// `what` when most of the region has no trusted code in any exposure.
pub(super) fn region_median(
    img: &[[f64; 3]],
    off: &[[f64; 3]],
    region: &[usize],
    channel: usize,
    what: &str,
) -> Result<f64> {
    let values: Vec<f64> = region
        .iter()
        .filter_map(|&i| {
            let v = img[i][channel] - off[i][channel];
            v.is_finite().then_some(v)
        })
        .collect();
    if values.len() * 2 < region.len() {
        bail!(
            "{what}: {} of {} camera pixels have no usable code at any exposure of the bracket \
             (saturated at the shortest or under-exposed at the longest): widen the bracket \
             (`stops`) or change the camera's base exposure",
            region.len() - values.len(),
            region.len()
        );
    }
    metrics::percentile(&values, 50.0).context("no value")
}

/// The camera's scale per channel from the reference spot: over the
/// camera pixels whose every subsample ray meets a real surface lit by the
/// spot (the product's geometry), the median of what the camera measured
/// (`lit - off`) over what the product predicts the spot adds there
/// (`rho / pi * dI * cos / d^2` per subsample, their mean); with the
/// medians of each and the pixel count.
#[allow(clippy::type_complexity)]
fn spot_scale(
    lit: &[[f64; 3]],
    off: &[[f64; 3]],
    real: &SceneGeometry,
    scene: &Showcase,
    camera: &PinholeDevice,
    spot: Spot,
) -> Result<([f64; 3], [f64; 3], [f64; 3], usize)> {
    let eye = DeviceRays::new(camera)?;
    let projector = scene
        .projectors
        .get(spot.projector)
        .context("the spot's projector is not in the scene")?;
    let rays = DeviceRays::new(&projector.device)?;
    // The spot's device value through the projector's profile (the
    // product's model where it has none).
    let di = device_intensity(DVec3::splat(f64::from(spot.value)), &projector.response)
        - device_intensity(DVec3::ZERO, &projector.response);
    let (cx, cy) = (f64::from(spot.centre.0), f64::from(spot.centre.1));
    let half = f64::from(spot.half);
    // What the spot adds at the surface a ray from the camera meets.
    let predict = |ray: &showcase_light::Ray| -> Option<DVec3> {
        let hit = real.closest_hit(ray, 0.0, f64::INFINITY)?;
        let normal = hit.facing_normal(ray.direction);
        let px = rays.project(hit.point)?;
        // Inside the square of pixels, by a margin of half a pixel.
        if (px.x - (cx + 0.5)).abs() > half || (px.y - (cy + 0.5)).abs() > half {
            return None;
        }
        if !rays.sees(real, hit.point, normal) {
            return None;
        }
        let to = rays.center() - hit.point;
        let d = to.length();
        let cos = normal.dot(to / d);
        if cos.is_nan() || cos <= 0.0 {
            return None;
        }
        let rho = scene.objects[hit.object as usize]
            .material
            .albedo_at(hit.uv.unwrap_or(glam::Vec2::ZERO))
            .as_dvec3();
        Some(rho * std::f64::consts::FRAC_1_PI * di * cos / (d * d))
    };
    // The light the spot sends out that the room sends back onto it.
    let back = DVec3::ONE + spot_return(real, scene, &rays, spot)?;
    let n = camera.width * camera.height;
    let pixels: Vec<(usize, DVec3)> = (0..n)
        .filter_map(|i| {
            let (x, y) = (f64::from(i % camera.width), f64::from(i / camera.width));
            let mut sum = DVec3::ZERO;
            for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                sum += predict(&eye.ray_through(DVec2::new(x + dx, y + dy))?)?;
            }
            Some((i as usize, back * sum / 4.0))
        })
        .collect();
    if pixels.len() < 9 {
        bail!(
            "the spot lights only {} camera pixels wholly: enlarge the spot (`spot_half`)",
            pixels.len()
        );
    }
    let unread = pixels
        .iter()
        .filter(|(i, _)| (0..3).any(|c| !(lit[*i][c] - off[*i][c]).is_finite()))
        .count();
    if unread * 2 > pixels.len() {
        bail!(
            "{unread} of the {} camera pixels the spot lights have no usable code at any \
             exposure of the bracket (saturated at the shortest): add shorter exposures \
             (`stops`) or lower the camera's base exposure",
            pixels.len()
        );
    }
    let median = |v: Vec<f64>| {
        let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        metrics::percentile(&v, 50.0).unwrap_or(f64::NAN)
    };
    let mut scale = [0.0; 3];
    let (mut measured, mut predicted) = ([0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let got = |i: usize| lit[i][c] - off[i][c];
        scale[c] = median(pixels.iter().map(|(i, p)| got(*i) / p[c]).collect());
        measured[c] = median(pixels.iter().map(|(i, _)| got(*i)).collect());
        predicted[c] = median(pixels.iter().map(|(_, p)| p[c]).collect());
    }
    if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        bail!(
            "the camera measured {measured:?} of the spot against a predicted {predicted:?} \
             W/m^2/sr: it does not see the spot lit; check the projector's calibration and that \
             nothing blocks the camera's view of that surface"
        );
    }
    Ok((scale, measured, predicted, pixels.len()))
}

/// Cosine-weighted directions [`spot_return`] follows.
const RETURN_DIRECTIONS: u32 = 4096;

/// The share of the spot's radiance that comes back to it off the other
/// real surfaces, per channel, one bounce: the spot as a small Lambertian
/// source of area `A` at its centre `x` (radiance `L`), a surface point
/// `y` at distance `r` gets `L A cos_x cos_y / r^2` and sends
/// `rho_y / pi` of it back, so `rho_x * E[rho_y / pi * A cos_x cos_y /
/// r^2]` over cosine-weighted directions from `x` (`r^2` at least `A`,
/// where the small-source picture ends). The camera measures this light
/// with the spot's own; the direct prediction alone left every profile's
/// peak 0.2 to 0.9 % low.
fn spot_return(
    real: &SceneGeometry,
    scene: &Showcase,
    rays: &DeviceRays,
    spot: Spot,
) -> Result<DVec3> {
    let (cx, cy) = (
        f64::from(spot.centre.0) + 0.5,
        f64::from(spot.centre.1) + 0.5,
    );
    let h = f64::from(spot.half) + 0.5;
    let at = |u: f64, v: f64| {
        rays.ray_through(DVec2::new(u, v))
            .and_then(|r| real.closest_hit(&r, 0.0, f64::INFINITY))
    };
    let (Some(centre), Some(a), Some(b), Some(c)) = (
        at(cx, cy),
        at(cx - h, cy - h),
        at(cx + h, cy - h),
        at(cx - h, cy + h),
    ) else {
        bail!("the spot's corners miss the real surfaces");
    };
    let area = (b.point - a.point).cross(c.point - a.point).length();
    let towards = rays.center() - centre.point;
    let normal = centre.facing_normal(-towards);
    let rho_x = scene.objects[centre.object as usize]
        .material
        .albedo_at(centre.uv.unwrap_or(glam::Vec2::ZERO))
        .as_dvec3();
    let origin = real.offset_point(centre.point, normal, towards);
    let mut sum = DVec3::ZERO;
    for k in 0..RETURN_DIRECTIONS {
        let u = showcase_light::sampling::stratified_point(
            k,
            RETURN_DIRECTIONS,
            (
                showcase_light::sampling::unit(2 * u64::from(k)),
                showcase_light::sampling::unit(2 * u64::from(k) + 1),
            ),
        );
        let dir = showcase_light::sampling::cosine_direction(normal, u);
        let ray = showcase_light::Ray::new(origin, dir);
        let Some(y) = real.closest_hit(&ray, 0.0, f64::INFINITY) else {
            continue;
        };
        let cos_x = dir.dot(normal);
        let cos_y = y.facing_normal(dir).dot(-dir);
        if !(cos_x > 0.0 && cos_y > 0.0) {
            continue;
        }
        let rho_y = scene.objects[y.object as usize]
            .material
            .albedo_at(y.uv.unwrap_or(glam::Vec2::ZERO))
            .as_dvec3();
        let r2 = (y.point - centre.point).length_squared().max(area);
        sum += rho_y * std::f64::consts::FRAC_1_PI * area * cos_x * cos_y / r2;
    }
    Ok(rho_x * sum / f64::from(RETURN_DIRECTIONS))
}

/// The reference spot: the camera pixel nearest its centre whose real
/// surface is flat around the spot and lit frontally by some projector;
/// the spot and the surface point at its centre.
fn choose_reference(
    real: &SceneGeometry,
    scene: &Showcase,
    camera: &PinholeDevice,
    half: u32,
) -> Result<(Spot, DVec3)> {
    let eye = DeviceRays::new(camera)?;
    let projectors: Vec<DeviceRays> = scene
        .projectors
        .iter()
        .map(|p| DeviceRays::new(&p.device))
        .collect::<Result<_, _>>()?;
    let (w, h) = (camera.width as i64, camera.height as i64);
    // Candidates in rings around the centre, nearest first.
    let mut candidates: Vec<(i64, i64)> = (-w / 3..=w / 3)
        .step_by(2)
        .flat_map(|dx| (-h / 3..=h / 3).step_by(2).map(move |dy| (dx, dy)))
        .collect();
    candidates.sort_by_key(|(dx, dy)| dx * dx + dy * dy);
    for (dx, dy) in candidates {
        let (x, y) = ((w / 2 + dx) as u32, (h / 2 + dy) as u32);
        let Some(ray) = eye.pixel_ray(x, y) else {
            continue;
        };
        let Some(hit) = real.closest_hit(&ray, 0.0, f64::INFINITY) else {
            continue;
        };
        let normal = hit.facing_normal(ray.direction);
        for (p, rays) in projectors.iter().enumerate() {
            let to = rays.center() - hit.point;
            let d = to.length();
            let cos = normal.dot(to / d);
            if cos < 0.7 || !rays.sees(real, hit.point, normal) {
                continue;
            }
            let Some(pixel) = rays.pixel_of(hit.point) else {
                continue;
            };
            let spot = Spot {
                projector: p,
                centre: pixel,
                half,
                value: 1.0,
            };
            // Flat around it: the spot's corners meet the same object on
            // the same plane.
            let flat = [(-1i64, -1i64), (1, -1), (-1, 1), (1, 1)]
                .iter()
                .all(|(sx, sy)| {
                    let c = DVec2::new(
                        f64::from(pixel.0) + 0.5 + (sx * i64::from(half)) as f64,
                        f64::from(pixel.1) + 0.5 + (sy * i64::from(half)) as f64,
                    );
                    rays.ray_through(c)
                        .and_then(|r| real.closest_hit(&r, 0.0, f64::INFINITY))
                        .is_some_and(|c| {
                            c.object == hit.object
                                && c.geometric_normal.dot(hit.geometric_normal) > 0.9995
                                && (c.point - hit.point).dot(hit.geometric_normal).abs() < 1e-4
                        })
                });
            if !flat {
                continue;
            }
            return Ok((spot, hit.point));
        }
    }
    bail!(
        "no real surface near the middle of the camera's view is flat and lit frontally by a \
         projector: aim the camera at a projector-lit surface of the cabinet"
    )
}

/// The camera did not move: the ramp's merged images before and after
/// agree over the brighter half of the screen's pixels (median relative
/// difference within 2 %; the dim end of the ramp is the camera's noise).
fn check_still(before: &[[f64; 3]], after: &[[f64; 3]], screen: &[usize]) -> Result<()> {
    check_still_of(before, after, screen, "the CRT's ramp")
}

/// [`check_still`] of any two images of `what` (a pattern shown twice).
pub(super) fn check_still_of(
    before: &[[f64; 3]],
    after: &[[f64; 3]],
    screen: &[usize],
    what: &str,
) -> Result<()> {
    let pairs: Vec<(f64, f64)> = screen
        .iter()
        .flat_map(|&i| (0..3).map(move |c| (before[i][c], after[i][c])))
        .filter(|(a, b)| a.is_finite() && b.is_finite() && *a > 0.0)
        .collect();
    let values: Vec<f64> = pairs.iter().map(|p| p.0).collect();
    let bright = metrics::percentile(&values, 50.0).unwrap_or(0.0);
    let diffs: Vec<f64> = pairs
        .iter()
        .filter(|(a, _)| *a >= bright)
        .map(|(a, b)| ((b - a) / a).abs())
        .collect();
    let median = metrics::percentile(&diffs, 50.0).unwrap_or(f64::INFINITY);
    if median.is_nan() || median > 0.02 {
        bail!(
            "the camera's first and last frames of {what} differ by {:.1} % (median over the \
             pixels compared): the camera or the mirror moved during the calibration; fix the \
             tripod and run it again",
            100.0 * median
        );
    }
    Ok(())
}

/// The CRT's light must rise with its drive (within the noise: a fall of
/// more than 2 % of the largest value, or any fall at all above a quarter
/// of the range, is an error).
fn check_monotonic(levels: &[(f64, f64)], channel: usize) -> Result<()> {
    check_rising(
        levels,
        channel,
        "the CRT's",
        "check that the face's output is not being processed (dynamic contrast, power saving) \
         and that nothing changed the light during the calibration",
    )
}

/// [`check_monotonic`] of `device`'s light, with `hint` saying what to
/// check.
pub(super) fn check_rising(
    levels: &[(f64, f64)],
    channel: usize,
    device: &str,
    hint: &str,
) -> Result<()> {
    let top = levels.iter().map(|l| l.1).fold(0.0, f64::max);
    for pair in levels.windows(2) {
        let ((d0, s0), (d1, s1)) = (pair[0], pair[1]);
        let tolerance = if s0 > 0.25 * top { 0.0 } else { 0.02 * top };
        if s1 < s0 - tolerance {
            bail!(
                "{device} measured light in channel {} falls from {s0:.4} at drive {d0:.3} to \
                 {s1:.4} at drive {d1:.3}: {hint}",
                CHANNELS[channel]
            );
        }
    }
    Ok(())
}

/// `seen = black + peak * d^gamma` through `(drive, seen)` pairs sorted by
/// drive, the first at drive 0, by least squares of the relative residuals
/// `(black + peak * d^gamma) / seen - 1` over every level measured above
/// the camera's floor (a black level too dim to measure is left to the
/// curve's shape): for each gamma, black and peak are a weighted linear
/// fit (black at least 0); gamma minimises the residual (golden section
/// over 0.5 to 5).
pub(super) fn fit_power(levels: &[(f64, f64)]) -> Result<(f64, f64, f64)> {
    if levels.first().is_none_or(|(d, _)| *d != 0.0) {
        bail!("no level at drive 0");
    }
    let points: Vec<(f64, f64)> = levels
        .iter()
        .copied()
        .filter(|(_, s)| s.is_finite() && *s > 0.0)
        .collect();
    let rising = points.iter().filter(|(d, _)| *d > 0.0).count();
    if rising < 3 {
        bail!("only {rising} levels rise above the camera's floor: the CRT shows no usable range");
    }
    // Black and peak for one gamma, and the sum of squared relative
    // residuals.
    let solve = |gamma: f64| -> (f64, f64, f64) {
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(d, s) in &points {
            let (x, w) = (d.powf(gamma), 1.0 / (s * s));
            a11 += w;
            a12 += w * x;
            a22 += w * x * x;
            b1 += w * s;
            b2 += w * s * x;
        }
        let det = a11 * a22 - a12 * a12;
        let (mut black, mut peak) = ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
        if black.is_nan() || black < 0.0 || !det.is_finite() || det <= 0.0 {
            black = 0.0;
            peak = b2 / a22;
        }
        let residual = points
            .iter()
            .map(|&(d, s)| ((black + peak * d.powf(gamma)) / s - 1.0).powi(2))
            .sum();
        (black, peak, residual)
    };
    let (mut lo, mut hi) = (0.5f64, 5.0f64);
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..80 {
        let (g1, g2) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
        if solve(g1).2 <= solve(g2).2 {
            hi = g2;
        } else {
            lo = g1;
        }
    }
    let gamma = 0.5 * (lo + hi);
    let (black, peak, _) = solve(gamma);
    if !(gamma.is_finite() && peak.is_finite() && peak > 0.0 && black.is_finite()) {
        bail!("the fitted curve is not a rising power (gamma {gamma}, peak {peak}, black {black})");
    }
    Ok((gamma, peak, black))
}

/// The largest relative error of `profile` on the held-out levels.
fn held_out_error(profile: &CrtPhotometry, levels: &[Level]) -> f64 {
    levels
        .iter()
        .filter(|l| l.held_out && l.seen > 0.0)
        .map(|l| {
            let mut d = Vec3::ZERO;
            d[l.channel] = l.drive as f32;
            let got = f64::from(profile.seen(d)[l.channel]);
            ((got - l.seen) / l.seen).abs()
        })
        .fold(0.0, f64::max)
}

/// What `calibrate --photometric` writes per face, and a scene's
/// `photometric_profile` reads: the profile its node encodes with, and
/// how it was measured.
#[derive(Clone, Debug, serde::Deserialize, Serialize)]
pub struct ProfileFile {
    /// The face it belongs to.
    pub face: String,
    /// The profile: the CRT's light through the mirror in the units of
    /// the real surfaces behind the glass (an ideal splitter: only `R / T`
    /// matters to a node).
    pub photometry: CrtPhotometry,
    /// Largest relative error on the held-out levels.
    #[serde(default)]
    pub held_out_error: Option<f64>,
    /// The camera's noise floor (code) when it was measured.
    #[serde(default)]
    pub noise_floor: Option<u32>,
}

impl From<&FaceCalibration> for ProfileFile {
    fn from(c: &FaceCalibration) -> Self {
        Self {
            face: c.face.clone(),
            photometry: c.profile,
            held_out_error: Some(if c.kept_previous {
                c.held_out_error_before
            } else {
                c.held_out_error
            }),
            noise_floor: Some(c.noise_floor),
        }
    }
}
