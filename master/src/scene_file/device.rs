//! Lights, projectors, cameras, CRT faces and observers of a scene file:
//! turning their tables into proto types, with degenerate geometry (a
//! singular camera matrix, a rotation that is not one, a zero direction)
//! rejected by name.

use super::error::{Ctx, SceneError};
use super::schema::{
    CalibrationDef, DeviceDef, FaceDef, LightDef, LightType, N3, Num, ObserverDef,
};
use glam::{DMat3, DVec3, Mat3, Quat, Vec3};
use showcase_proto::{
    BeamSplitter, Camera, CameraResponse, CrtFace, CrtPhotometry, CrtResponse, Light, LightSource,
    Observer, PinholeDevice, Plane, Pose, Projector, ProjectorResponse, Rect3,
};
use std::path::Path;

/// A rotation matrix whose `R^T R` deviates from the identity by more than
/// this is rejected; a smaller deviation (rounded decimals) is projected
/// onto the nearest rotation.
pub(crate) const ROTATION_TOLERANCE: f64 = 1e-3;
/// Default interpupillary distance in metres.
/// Default near plane in metres.
pub(crate) const DEFAULT_NEAR: f64 = 0.01;
/// Default far plane in metres.
pub(crate) const DEFAULT_FAR: f64 = 100.0;
/// Default number of point samples of an area light.
pub(crate) const DEFAULT_AREA_SAMPLES: u32 = 16;

pub(crate) fn v3(n: N3) -> Vec3 {
    Vec3::new(n[0].0 as f32, n[1].0 as f32, n[2].0 as f32)
}

pub(crate) fn dv3(n: N3) -> DVec3 {
    DVec3::new(n[0].0, n[1].0, n[2].0)
}

/// A unit quaternion from `[x, y, z, w]`; `None` when it has no length.
pub(crate) fn quat(q: [Num; 4]) -> Option<Quat> {
    let q = glam::DQuat::from_xyzw(q[0].0, q[1].0, q[2].0, q[3].0);
    (q.length() > 1e-9).then(|| q.normalize().as_quat())
}

fn need<T: Copy>(
    ctx: &Ctx,
    label: &str,
    key: &str,
    what: &str,
    v: Option<T>,
) -> Result<T, SceneError> {
    v.ok_or_else(|| ctx.invalid(format!("{label}.{key}"), format!("a {what} needs `{key}`")))
}

fn reject(ctx: &Ctx, label: &str, what: &str, keys: &[(&str, bool)]) -> Result<(), SceneError> {
    match keys.iter().find(|(_, present)| *present) {
        Some((key, _)) => Err(ctx.invalid(
            format!("{label}.{key}"),
            format!("`{key}` does not apply to a {what}"),
        )),
        None => Ok(()),
    }
}

/// One `[[light]]`.
pub(crate) fn light(ctx: &Ctx, label: &str, d: &LightDef) -> Result<LightSource, SceneError> {
    let light = match d.kind {
        LightType::Point => {
            reject(
                ctx,
                label,
                "point light",
                &[
                    ("direction", d.direction.is_some()),
                    ("inner_deg", d.inner_deg.is_some()),
                    ("outer_deg", d.outer_deg.is_some()),
                    ("corner", d.corner.is_some()),
                    ("edge_u", d.edge_u.is_some()),
                    ("edge_v", d.edge_v.is_some()),
                    ("radiance", d.radiance.is_some()),
                    ("samples", d.samples.is_some()),
                ],
            )?;
            Light::Point {
                position: v3(need(ctx, label, "position", "point light", d.position)?),
                intensity: v3(need(ctx, label, "intensity", "point light", d.intensity)?),
            }
        }
        LightType::Spot => {
            reject(
                ctx,
                label,
                "spot light",
                &[
                    ("corner", d.corner.is_some()),
                    ("edge_u", d.edge_u.is_some()),
                    ("edge_v", d.edge_v.is_some()),
                    ("radiance", d.radiance.is_some()),
                    ("samples", d.samples.is_some()),
                ],
            )?;
            let direction = v3(need(ctx, label, "direction", "spot light", d.direction)?);
            if direction.length_squared() < 1e-12 {
                return Err(ctx.invalid(format!("{label}.direction"), "spot direction is zero"));
            }
            Light::Spot {
                position: v3(need(ctx, label, "position", "spot light", d.position)?),
                direction,
                intensity: v3(need(ctx, label, "intensity", "spot light", d.intensity)?),
                inner_deg: need(ctx, label, "inner_deg", "spot light", d.inner_deg)?.0 as f32,
                outer_deg: need(ctx, label, "outer_deg", "spot light", d.outer_deg)?.0 as f32,
            }
        }
        LightType::Area => {
            reject(
                ctx,
                label,
                "area light",
                &[
                    ("position", d.position.is_some()),
                    ("intensity", d.intensity.is_some()),
                    ("direction", d.direction.is_some()),
                    ("inner_deg", d.inner_deg.is_some()),
                    ("outer_deg", d.outer_deg.is_some()),
                ],
            )?;
            let edge_u = dv3(need(ctx, label, "edge_u", "area light", d.edge_u)?);
            let edge_v = dv3(need(ctx, label, "edge_v", "area light", d.edge_v)?);
            if edge_u.cross(edge_v).length() < 1e-8 {
                return Err(ctx.invalid(
                    format!("{label}.edge_v"),
                    format!("edges {edge_u} and {edge_v} span no area"),
                ));
            }
            Light::Area {
                corner: v3(need(ctx, label, "corner", "area light", d.corner)?),
                edge_u: edge_u.as_vec3(),
                edge_v: edge_v.as_vec3(),
                radiance: v3(need(ctx, label, "radiance", "area light", d.radiance)?),
                samples: d.samples.unwrap_or(DEFAULT_AREA_SAMPLES),
            }
        }
    };
    Ok(LightSource {
        name: d.name.clone(),
        light,
    })
}

fn rows3(r: [N3; 3]) -> DMat3 {
    DMat3::from_cols_array_2d(&r.map(|row| row.map(|x| x.0))).transpose()
}

fn rows3_f64(r: [[f64; 3]; 3]) -> DMat3 {
    DMat3::from_cols_array_2d(&r).transpose()
}

/// Check a camera matrix: upper triangular, `k[2][2] = 1`, positive
/// focal lengths (hence non-singular).
fn camera_matrix(ctx: &Ctx, field: &str, k: DMat3) -> Result<DMat3, SceneError> {
    if k.to_cols_array().iter().any(|x| !x.is_finite()) {
        return Err(ctx.invalid(field, "camera matrix has a non-finite entry"));
    }
    let row2 = k.row(2);
    if (row2 - DVec3::Z).abs().max_element() > 1e-9 || k.x_axis.y.abs() > 1e-9 {
        return Err(ctx.invalid(
            field,
            format!(
                "camera matrix must be upper triangular with last row [0, 0, 1], got rows {:?}",
                [k.row(0).to_array(), k.row(1).to_array(), row2.to_array()]
            ),
        ));
    }
    let (fx, fy) = (k.x_axis.x, k.y_axis.y);
    if fx * fy == 0.0 || k.determinant().abs() < 1e-12 {
        return Err(ctx.invalid(
            field,
            format!("camera matrix is singular (fx={fx}, fy={fy})"),
        ));
    }
    if fx < 0.0 || fy < 0.0 {
        return Err(ctx.invalid(
            field,
            format!("focal lengths fx={fx} fy={fy} must be positive"),
        ));
    }
    let mut k = k;
    k.x_axis.y = 0.0;
    k.x_axis.z = 0.0;
    k.y_axis.z = 0.0;
    k.z_axis.z = 1.0;
    Ok(k)
}

/// Check a rotation and project it onto the nearest rotation (polar
/// decomposition) so that rounded decimals pass exact checks downstream.
pub(crate) fn rotation(ctx: &Ctx, field: &str, r: DMat3) -> Result<DMat3, SceneError> {
    if r.to_cols_array().iter().any(|x| !x.is_finite()) {
        return Err(ctx.invalid(field, "rotation has a non-finite entry"));
    }
    let err = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    if err > ROTATION_TOLERANCE {
        return Err(ctx.invalid(
            field,
            format!("rotation is not orthonormal (R^T R deviates from I by {err:.2e}, tolerance {ROTATION_TOLERANCE:e})"),
        ));
    }
    if r.determinant() < 0.0 {
        return Err(ctx.invalid(field, "rotation is a reflection (det R < 0)"));
    }
    let m = nalgebra::Matrix3::from_column_slice(&r.to_cols_array());
    let svd = m.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(ctx.invalid(field, "rotation could not be decomposed"));
    };
    let nearest = u * vt;
    Ok(DMat3::from_cols_slice(nearest.as_slice()))
}

/// The geometry of a projector or camera.
pub(crate) fn pinhole(
    ctx: &Ctx,
    label: &str,
    d: &DeviceDef,
    base_dir: &Path,
) -> Result<PinholeDevice, SceneError> {
    let inline = d.camera_matrix.is_some() || d.rotation.is_some() || d.translation.is_some();
    let sources = [d.look_at.is_some(), inline, d.calibration.is_some()];
    if sources.iter().filter(|s| **s).count() != 1 {
        return Err(ctx.invalid(
            label,
            "give exactly one of `look_at`, `camera_matrix` + `rotation` + `translation`, or `calibration`",
        ));
    }
    let mut dev = if let Some(la) = &d.look_at {
        let (eye, target) = (dv3(la.eye), dv3(la.target));
        let up = la.up.map_or(DVec3::Y, dv3);
        let dir = target - eye;
        if dir.length() < 1e-9 {
            return Err(ctx.invalid(
                format!("{label}.look_at"),
                format!("eye and target are both {eye}"),
            ));
        }
        if dir.normalize().cross(up).length() < 1e-6 {
            return Err(ctx.invalid(
                format!("{label}.look_at.up"),
                format!("up {up} is parallel to the viewing direction {dir}"),
            ));
        }
        let fov = la.fov_deg.0;
        if !(fov > 0.0 && fov < 179.0) {
            return Err(ctx.invalid(
                format!("{label}.look_at.fov_deg"),
                format!("{fov} is outside (0, 179)"),
            ));
        }
        let (w, h) = size(ctx, label, d.width, d.height, None)?;
        PinholeDevice::look_at(eye, target, up, fov, w, h)
    } else if inline {
        let k = need(ctx, label, "camera_matrix", "device", d.camera_matrix)?;
        let r = need(ctx, label, "rotation", "device", d.rotation)?;
        let t = need(ctx, label, "translation", "device", d.translation)?;
        let (w, h) = size(ctx, label, d.width, d.height, None)?;
        PinholeDevice {
            width: w,
            height: h,
            k: camera_matrix(ctx, &format!("{label}.camera_matrix"), rows3(k))?,
            rotation: rotation(ctx, &format!("{label}.rotation"), rows3(r))?,
            translation: dv3(t),
            dist_coeffs: d.dist_coeffs.map_or([0.0; 5], |c| c.map(|x| x.0)),
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
        }
    } else {
        let file = d.calibration.as_deref().unwrap_or_default();
        calibrated(ctx, label, (d.width, d.height), &base_dir.join(file))?
    };
    if let (Some(c), false) = (d.dist_coeffs, inline) {
        dev.dist_coeffs = c.map(|x| x.0);
    }
    dev.near = d.near.map_or(DEFAULT_NEAR, |n| n.0);
    dev.far = d.far.map_or(DEFAULT_FAR, |f| f.0);
    if !(dev.near > 0.0 && dev.far > dev.near) {
        return Err(ctx.invalid(
            format!("{label}.far"),
            format!("need 0 < near < far, got near={} far={}", dev.near, dev.far),
        ));
    }
    Ok(dev)
}

fn size(
    ctx: &Ctx,
    label: &str,
    w: Option<u32>,
    h: Option<u32>,
    from_file: Option<(Option<u32>, Option<u32>)>,
) -> Result<(u32, u32), SceneError> {
    let (fw, fh) = from_file.unwrap_or((None, None));
    let pick = |key: &str, scene: Option<u32>, file: Option<u32>| match (scene, file) {
        (Some(a), Some(b)) if a != b => Err(ctx.invalid(
            format!("{label}.{key}"),
            format!("{a} differs from {b} in the calibration file"),
        )),
        (Some(a), _) | (None, Some(a)) => Ok(a),
        (None, None) => {
            Err(ctx.invalid(format!("{label}.{key}"), format!("a device needs `{key}`")))
        }
    };
    Ok((pick("width", w, fw)?, pick("height", h, fh)?))
}

/// The JSON file `path` that the scene's `field` names, parsed; errors
/// name both, with the line where the JSON is wrong.
fn read_json<T: serde::de::DeserializeOwned>(
    ctx: &Ctx,
    field: &str,
    path: &Path,
) -> Result<T, SceneError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| ctx.referenced(field, path, None, format!("cannot read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| {
        ctx.referenced(
            field,
            path,
            Some(e.line()).filter(|l| *l > 0),
            e.to_string(),
        )
    })
}

/// A device from the JSON written by `showcase-master calibrate`; `size`
/// is the table's `width` and `height`, which the file must agree with.
pub(crate) fn calibrated(
    ctx: &Ctx,
    label: &str,
    size_given: (Option<u32>, Option<u32>),
    path: &Path,
) -> Result<PinholeDevice, SceneError> {
    let field = format!("{label}.calibration");
    let c: CalibrationDef = read_json(ctx, &field, path)?;
    let bad = |what: &str, problem: String| {
        ctx.referenced(&field, path, None, format!("{what}: {problem}"))
    };
    let k = camera_matrix(ctx, &field, rows3_f64(c.camera_matrix))
        .map_err(|e| bad("camera_matrix", problem_of(e)))?;
    let r =
        rotation(ctx, &field, rows3_f64(c.rotation)).map_err(|e| bad("rotation", problem_of(e)))?;
    let t = DVec3::from_array(c.translation);
    if !t.is_finite() {
        return Err(bad("translation", "has a non-finite entry".into()));
    }
    let mut dist = [0.0; 5];
    if let Some(dc) = &c.dist_coeffs {
        if dc.len() > 5 {
            return Err(bad(
                "dist_coeffs",
                format!("{} coefficients, at most 5 [k1, k2, p1, p2, k3]", dc.len()),
            ));
        }
        dist[..dc.len()].copy_from_slice(dc);
    }
    let (w, h) = size(
        ctx,
        label,
        size_given.0,
        size_given.1,
        Some((c.width, c.height)),
    )?;
    let dev = PinholeDevice {
        width: w,
        height: h,
        k,
        rotation: r,
        translation: t,
        dist_coeffs: dist,
        near: DEFAULT_NEAR,
        far: DEFAULT_FAR,
    };
    if let Some(p) = c.projection {
        let ours = dev.projection();
        let scale = p.iter().flatten().fold(1.0f64, |m, x| m.max(x.abs()));
        let dev_err = p
            .iter()
            .flatten()
            .zip(ours.iter().flatten())
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        if dev_err.is_nan() || dev_err > 1e-4 * scale {
            return Err(bad(
                "projection",
                format!("disagrees with camera_matrix [rotation | translation] by {dev_err:.3e}"),
            ));
        }
    }
    Ok(dev)
}

fn problem_of(e: SceneError) -> String {
    match e {
        SceneError::Invalid { problem, .. } => problem,
        other => other.to_string(),
    }
}

/// One `[[projector]]`.
pub(crate) fn projector(
    ctx: &Ctx,
    label: &str,
    d: &DeviceDef,
    base_dir: &Path,
) -> Result<Projector, SceneError> {
    reject(
        ctx,
        label,
        "projector (it is a camera key)",
        &[
            ("gain", d.gain.is_some()),
            ("exposure_s", d.exposure_s.is_some()),
            ("read_noise", d.read_noise.is_some()),
            ("shot_noise", d.shot_noise.is_some()),
            ("bits", d.bits.is_some()),
            ("gamma_rgb", d.gamma_rgb.is_some()),
            ("knee", d.knee.is_some()),
            ("shoulder", d.shoulder.is_some()),
        ],
    )?;
    let def = ProjectorResponse::default();
    let f = |n: Option<Num>, default: f32| n.map_or(default, |x| x.0 as f32);
    Ok(Projector {
        name: d.name.clone(),
        device: pinhole(ctx, label, d, base_dir)?,
        response: ProjectorResponse {
            gamma: f(d.gamma, def.gamma),
            eta: f(d.eta, def.eta),
            black_level: f(d.black_level, def.black_level),
            wheel_segments: d
                .wheel_segments
                .as_ref()
                .map_or(def.wheel_segments, |s| s.iter().map(|c| v3(*c)).collect()),
            wheel_period_s: f(d.wheel_period_s, def.wheel_period_s),
            photometry: match (&d.photometry, &d.photometric_profile) {
                (Some(_), Some(_)) => {
                    return Err(ctx.invalid(
                        format!("{label}.photometric_profile"),
                        "give the measured profile or the device (`photometry`), not both",
                    ));
                }
                (Some(c), None) => Some(CrtResponse {
                    gamma: v3(c.gamma),
                    peak: v3(c.peak),
                    black_level: c.black_level.map_or(Vec3::ZERO, v3),
                }),
                (None, Some(file)) => Some(projector_profile(
                    ctx,
                    label,
                    &d.name,
                    &base_dir.join(file),
                )?),
                (None, None) => None,
            },
        },
    })
}

/// A projector's photometry from the profile `calibrate --photometric`
/// wrote ([`crate::calibrate::photometric::ProjectorProfileFile`]), which
/// must name this projector and hold a valid curve.
fn projector_profile(
    ctx: &Ctx,
    label: &str,
    projector: &str,
    path: &Path,
) -> Result<CrtResponse, SceneError> {
    use showcase_proto::Validate;
    let field = format!("{label}.photometric_profile");
    let file: crate::calibrate::photometric::ProjectorProfileFile = read_json(ctx, &field, path)?;
    if file.projector != projector {
        return Err(ctx.referenced(
            &field,
            path,
            None,
            format!(
                "the profile is of projector {:?}, not {projector:?}: point this projector at \
                 its own profile",
                file.projector
            ),
        ));
    }
    let check = ProjectorResponse {
        photometry: Some(file.photometry),
        ..ProjectorResponse::default()
    };
    check
        .validate()
        .map_err(|e| ctx.referenced(&field, path, None, e.to_string()))?;
    Ok(file.photometry)
}

/// One `[[camera]]`.
pub(crate) fn camera(
    ctx: &Ctx,
    label: &str,
    d: &DeviceDef,
    base_dir: &Path,
) -> Result<Camera, SceneError> {
    reject(
        ctx,
        label,
        "camera (it is a projector key)",
        &[
            ("eta", d.eta.is_some()),
            ("black_level", d.black_level.is_some()),
            ("wheel_segments", d.wheel_segments.is_some()),
            ("wheel_period_s", d.wheel_period_s.is_some()),
            ("photometry", d.photometry.is_some()),
            ("photometric_profile", d.photometric_profile.is_some()),
        ],
    )?;
    let def = CameraResponse::default();
    let f = |n: Option<Num>, default: f32| n.map_or(default, |x| x.0 as f32);
    Ok(Camera {
        name: d.name.clone(),
        device: pinhole(ctx, label, d, base_dir)?,
        response: CameraResponse {
            gamma: match (d.gamma, d.gamma_rgb) {
                (Some(_), Some(_)) => {
                    return Err(ctx.invalid(
                        format!("{label}.gamma"),
                        "give `gamma` or `gamma_rgb` (one per channel), not both",
                    ));
                }
                (Some(g), None) => Vec3::splat(g.0 as f32),
                (None, Some(g)) => v3(g),
                (None, None) => def.gamma,
            },
            knee: f(d.knee, def.knee),
            shoulder: f(d.shoulder, def.shoulder),
            gain: f(d.gain, def.gain),
            exposure_s: f(d.exposure_s, def.exposure_s),
            read_noise: f(d.read_noise, def.read_noise),
            shot_noise: f(d.shot_noise, def.shot_noise),
            bits: d.bits.unwrap_or(def.bits),
        },
    })
}

/// One `[[face]]`.
pub(crate) fn face(
    ctx: &Ctx,
    label: &str,
    d: &FaceDef,
    base_dir: &Path,
) -> Result<CrtFace, SceneError> {
    let normal = dv3(d.mirror.normal);
    if normal.length() < 1e-9 {
        return Err(ctx.invalid(format!("{label}.mirror.normal"), "mirror normal is zero"));
    }
    let n = normal.normalize();
    Ok(CrtFace {
        name: d.name.clone(),
        screen: Rect3 {
            origin: v3(d.screen.origin),
            right: v3(d.screen.right),
            down: v3(d.screen.down),
        },
        mirror: Plane {
            normal: n.as_vec3(),
            offset: n.dot(dv3(d.mirror.point)) as f32,
        },
        width: d.width,
        height: d.height,
        photometry: match &d.photometric_profile {
            Some(file) => {
                let stated = [
                    d.gamma.is_some(),
                    d.crt.is_some(),
                    d.beam_splitter.is_some(),
                ];
                if stated.iter().any(|s| *s) {
                    return Err(ctx.invalid(
                        format!("{label}.photometric_profile"),
                        "give the measured profile or the devices (`gamma`, `crt`, \
                         `beam_splitter`), not both",
                    ));
                }
                photometric_profile(ctx, label, &d.name, &base_dir.join(file))?
            }
            None => face_photometry(ctx, label, d)?,
        },
    })
}

/// A face's photometry from the profile `calibrate --photometric` wrote
/// ([`crate::calibrate::photometric::ProfileFile`]), which must name this
/// face and hold a valid chain.
fn photometric_profile(
    ctx: &Ctx,
    label: &str,
    face: &str,
    path: &Path,
) -> Result<CrtPhotometry, SceneError> {
    use showcase_proto::Validate;
    let field = format!("{label}.photometric_profile");
    let file: crate::calibrate::photometric::ProfileFile = read_json(ctx, &field, path)?;
    if file.face != face {
        return Err(ctx.referenced(
            &field,
            path,
            None,
            format!(
                "the profile is of face {:?}, not {face:?}: point this face at its own profile",
                file.face
            ),
        ));
    }
    file.photometry
        .validate()
        .map_err(|e| ctx.referenced(&field, path, None, e.to_string()))?;
    Ok(file.photometry)
}

/// A face's CRT and beam splitter: `gamma` alone is a nominal CRT of that
/// gamma behind an ideal combiner; `[face.crt]` and `[face.beam_splitter]`
/// state the device per channel.
fn face_photometry(ctx: &Ctx, label: &str, d: &FaceDef) -> Result<CrtPhotometry, SceneError> {
    let mut photometry = CrtPhotometry::nominal(d.gamma.map_or(2.2, |g| g.0 as f32));
    if let Some(crt) = &d.crt {
        if d.gamma.is_some() {
            return Err(ctx.invalid(
                format!("{label}.gamma"),
                "give `gamma` or `[face.crt]` (its own gamma per channel), not both",
            ));
        }
        photometry.crt = CrtResponse {
            gamma: v3(crt.gamma),
            peak: v3(crt.peak),
            black_level: crt.black_level.map_or(Vec3::ZERO, v3),
        };
    }
    if let Some(s) = &d.beam_splitter {
        photometry.splitter = BeamSplitter {
            transmission: v3(s.transmission),
            reflection: v3(s.reflection),
        };
    }
    Ok(photometry)
}

/// One `[[observer]]`: the head looks along its local -z with y up.
pub(crate) fn observer(ctx: &Ctx, label: &str, d: &ObserverDef) -> Result<Observer, SceneError> {
    let position = dv3(d.position);
    let orientation = match (d.look_at, d.orientation_quat) {
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(label, "give `look_at` or `orientation_quat`, not both"));
        }
        (Some(target), None) => {
            let dir = dv3(target) - position;
            let up = d.up.map_or(DVec3::Y, dv3);
            if dir.length() < 1e-9 {
                return Err(ctx.invalid(
                    format!("{label}.look_at"),
                    format!("the head is at its target {position}"),
                ));
            }
            let z = -dir.normalize();
            let x = up.cross(z);
            if x.length() < 1e-6 {
                return Err(ctx.invalid(
                    format!("{label}.up"),
                    format!("up {up} is parallel to the viewing direction"),
                ));
            }
            let x = x.normalize();
            let y = z.cross(x);
            Quat::from_mat3(&Mat3::from_cols(x.as_vec3(), y.as_vec3(), z.as_vec3())).normalize()
        }
        (None, Some(q)) => quat(q).ok_or_else(|| {
            ctx.invalid(format!("{label}.orientation_quat"), "quaternion is zero")
        })?,
        (None, None) => {
            if d.up.is_some() {
                return Err(ctx.invalid(format!("{label}.up"), "`up` needs `look_at`"));
            }
            Quat::IDENTITY
        }
    };
    Ok(Observer {
        name: d.name.clone(),
        head: Pose {
            position: position.as_vec3(),
            orientation,
        },
        ipd: d.ipd.map_or(Observer::DEFAULT_IPD, |x| x.0 as f32),
    })
}
