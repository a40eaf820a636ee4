//! Validation of everything that crosses a trust boundary: floats finite,
//! indices in range, matrices non-degenerate, names sane. A failure names
//! the offending field, e.g. `objects[3].transform.scale`.

use crate::message::{
    ElementLight, Hello, IlluminationBody, IlluminationMesh, MAX_ILLUMINATION_ELEMENTS,
    MAX_ILLUMINATION_VALUE, Message, NodeStats, Welcome,
};
use crate::scene::*;
use glam::{DMat3, DVec3, Quat, Vec3};
use std::collections::HashSet;

/// A value that broke a rule, with the path of the field that holds it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {problem}")]
pub struct ValidationError {
    /// Path of the offending field, e.g. `projectors[0].device.k`.
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

/// Longest name accepted for any object, light, device or node.
pub const MAX_NAME_LEN: usize = 256;
/// Largest image dimension accepted for any device.
pub const MAX_RESOLUTION: u32 = 16_384;

/// Types that can check their own invariants.
pub trait Validate {
    /// `Ok` when every invariant holds; otherwise the first broken one.
    fn validate(&self) -> Result<(), ValidationError>;
}

type R = Result<(), ValidationError>;

fn fail(field: impl Into<String>, problem: impl Into<String>) -> R {
    Err(ValidationError {
        field: field.into(),
        problem: problem.into(),
    })
}

fn finite(field: &dyn Fn() -> String, x: f64) -> R {
    if x.is_finite() {
        Ok(())
    } else {
        fail(field(), format!("value {x} is not finite"))
    }
}

fn finite3(field: &dyn Fn() -> String, v: Vec3) -> R {
    v.to_array()
        .into_iter()
        .try_for_each(|c| finite(field, c as f64))
}

fn nonneg3(field: &dyn Fn() -> String, v: Vec3) -> R {
    finite3(field, v)?;
    if v.min_element() < 0.0 {
        return fail(field(), format!("{v} has a negative component"));
    }
    Ok(())
}

fn unit_quat(field: &dyn Fn() -> String, q: Quat) -> R {
    q.to_array()
        .into_iter()
        .try_for_each(|c| finite(field, c as f64))?;
    if (q.length() - 1.0).abs() > 1e-3 {
        return fail(field(), format!("quaternion {q} is not unit length"));
    }
    Ok(())
}

fn name(field: &dyn Fn() -> String, s: &str) -> R {
    if s.is_empty() {
        return fail(field(), "name is empty");
    }
    if s.len() > MAX_NAME_LEN {
        return fail(field(), format!("name is longer than {MAX_NAME_LEN} bytes"));
    }
    if s.chars().any(char::is_control) {
        return fail(field(), format!("name {s:?} has control characters"));
    }
    Ok(())
}

fn unique<'a>(list: &str, names: impl Iterator<Item = &'a str>) -> R {
    let mut seen = HashSet::new();
    for (i, n) in names.enumerate() {
        if !seen.insert(n) {
            return fail(format!("{list}[{i}].name"), format!("duplicate name {n:?}"));
        }
    }
    Ok(())
}

fn resolution(field: &dyn Fn() -> String, w: u32, h: u32) -> R {
    if w == 0 || h == 0 || w > MAX_RESOLUTION || h > MAX_RESOLUTION {
        return fail(
            field(),
            format!("resolution {w}x{h} is outside 1..={MAX_RESOLUTION}"),
        );
    }
    Ok(())
}

impl Validate for Mesh {
    fn validate(&self) -> R {
        let n = self.positions.len();
        if n > u32::MAX as usize {
            return fail("positions", "too many vertices");
        }
        for (i, p) in self.positions.iter().enumerate() {
            finite3(&|| format!("positions[{i}]"), *p)?;
        }
        if !self.normals.is_empty() && self.normals.len() != n {
            return fail(
                "normals",
                format!("{} normals for {n} positions", self.normals.len()),
            );
        }
        for (i, v) in self.normals.iter().enumerate() {
            finite3(&|| format!("normals[{i}]"), *v)?;
        }
        if !self.uvs.is_empty() && self.uvs.len() != n {
            return fail("uvs", format!("{} uvs for {n} positions", self.uvs.len()));
        }
        for (i, t) in self.uvs.iter().enumerate() {
            finite3(&|| format!("uvs[{i}]"), t.extend(0.0))?;
        }
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(bad) = t.iter().find(|&&v| v as usize >= n) {
                return fail(
                    format!("triangles[{i}]"),
                    format!("vertex index {bad} is out of range for {n} positions"),
                );
            }
        }
        Ok(())
    }
}

impl Validate for Material {
    fn validate(&self) -> R {
        nonneg3(&|| "albedo".into(), self.albedo)?;
        if self.albedo.max_element() > 1.0 {
            return fail("albedo", format!("{} exceeds 1", self.albedo));
        }
        nonneg3(&|| "emission".into(), self.emission)?;
        if let Some(t) = &self.texture {
            let (a, b, f) = match t {
                AlbedoTexture::Checker { a, b, .. } => (*a, *b, 1.0),
                AlbedoTexture::Wood { light, dark, rings } => (*light, *dark, *rings),
            };
            for (field, v) in [("texture.a", a), ("texture.b", b)] {
                nonneg3(&|| field.into(), v)?;
                if v.max_element() > 1.0 {
                    return fail(field, format!("{v} exceeds 1"));
                }
            }
            finite(&|| "texture".into(), f as f64)?;
        }
        if let Some(m) = &self.reflectance_map {
            name(&|| "reflectance_map".into(), m)?;
        }
        Ok(())
    }
}

impl Validate for Transform {
    fn validate(&self) -> R {
        finite3(&|| "translation".into(), self.translation)?;
        unit_quat(&|| "rotation".into(), self.rotation)?;
        finite3(&|| "scale".into(), self.scale)?;
        if self.scale.abs().min_element() < 1e-9 {
            return fail("scale", format!("scale {} is degenerate", self.scale));
        }
        Ok(())
    }
}

impl Validate for Light {
    fn validate(&self) -> R {
        match self {
            Light::Point {
                position,
                intensity,
            } => {
                finite3(&|| "position".into(), *position)?;
                nonneg3(&|| "intensity".into(), *intensity)
            }
            Light::Spot {
                position,
                direction,
                intensity,
                inner_deg,
                outer_deg,
            } => {
                finite3(&|| "position".into(), *position)?;
                finite3(&|| "direction".into(), *direction)?;
                if direction.length_squared() < 1e-12 {
                    return fail("direction", "spot direction is zero");
                }
                nonneg3(&|| "intensity".into(), *intensity)?;
                finite(&|| "inner_deg".into(), *inner_deg as f64)?;
                finite(&|| "outer_deg".into(), *outer_deg as f64)?;
                if !(0.0..=*outer_deg).contains(inner_deg) || *outer_deg > 90.0 {
                    return fail(
                        "outer_deg",
                        format!(
                            "cone {inner_deg}..{outer_deg} degrees is not 0 <= inner <= outer <= 90"
                        ),
                    );
                }
                Ok(())
            }
            Light::Area {
                corner,
                edge_u,
                edge_v,
                radiance,
                samples,
            } => {
                finite3(&|| "corner".into(), *corner)?;
                finite3(&|| "edge_u".into(), *edge_u)?;
                finite3(&|| "edge_v".into(), *edge_v)?;
                if edge_u.cross(*edge_v).length_squared() < 1e-16 {
                    return fail("edge_v", "area light has zero area");
                }
                nonneg3(&|| "radiance".into(), *radiance)?;
                if !(1..=4096).contains(samples) {
                    return fail("samples", format!("{samples} is outside 1..=4096"));
                }
                Ok(())
            }
        }
    }
}

fn rotation_matrix(field: &dyn Fn() -> String, r: DMat3) -> R {
    for c in r.to_cols_array() {
        finite(field, c)?;
    }
    let err = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    if err > 1e-6 {
        return fail(
            field(),
            format!("rotation is not orthonormal (R^T R deviates by {err:.2e})"),
        );
    }
    if r.determinant() < 0.0 {
        return fail(field(), "rotation is a reflection (det R < 0)");
    }
    Ok(())
}

impl Validate for PinholeDevice {
    fn validate(&self) -> R {
        resolution(&|| "width".into(), self.width, self.height)?;
        let k = self.k;
        for c in k.to_cols_array() {
            finite(&|| "k".into(), c)?;
        }
        if k.row(2) != DVec3::new(0.0, 0.0, 1.0) || k.x_axis.y != 0.0 {
            return fail(
                "k",
                "camera matrix is not upper triangular with k[2][2] = 1",
            );
        }
        if !(k.x_axis.x > 0.0 && k.y_axis.y > 0.0) {
            return fail(
                "k",
                format!(
                    "focal lengths fx={} fy={} must be positive",
                    k.x_axis.x, k.y_axis.y
                ),
            );
        }
        rotation_matrix(&|| "rotation".into(), self.rotation)?;
        for c in self.translation.to_array() {
            finite(&|| "translation".into(), c)?;
        }
        for c in self.dist_coeffs {
            finite(&|| "dist_coeffs".into(), c)?;
        }
        finite(&|| "near".into(), self.near)?;
        finite(&|| "far".into(), self.far)?;
        if !(self.near > 0.0 && self.far > self.near) {
            return fail(
                "far",
                format!(
                    "need 0 < near < far, got near={} far={}",
                    self.near, self.far
                ),
            );
        }
        Ok(())
    }
}

impl Validate for ProjectorResponse {
    fn validate(&self) -> R {
        for (f, v) in [
            ("gamma", self.gamma),
            ("eta", self.eta),
            ("black_level", self.black_level),
            ("wheel_period_s", self.wheel_period_s),
        ] {
            finite(&|| f.into(), v as f64)?;
            if v < 0.0 {
                return fail(f, format!("{v} is negative"));
            }
        }
        if self.gamma <= 0.0 {
            return fail("gamma", "gamma must be positive");
        }
        if !self.wheel_segments.is_empty() && self.wheel_period_s <= 0.0 {
            return fail("wheel_period_s", "a colour wheel needs a positive period");
        }
        if self.wheel_segments.len() > 64 {
            return fail("wheel_segments", "more than 64 segments");
        }
        for (i, s) in self.wheel_segments.iter().enumerate() {
            nonneg3(&|| format!("wheel_segments[{i}]"), *s)?;
        }
        if let Some(p) = &self.photometry {
            for (name, v) in [
                ("photometry.gamma", p.gamma),
                ("photometry.peak", p.peak),
                ("photometry.black_level", p.black_level),
            ] {
                finite3(&|| name.into(), v)?;
            }
            if p.gamma.min_element() <= 0.0 {
                return fail("photometry.gamma", "gamma must be positive");
            }
            if p.peak.min_element() <= 0.0 {
                return fail("photometry.peak", "peak intensity must be positive");
            }
            nonneg3(&|| "photometry.black_level".into(), p.black_level)?;
        }
        Ok(())
    }
}

impl Validate for CameraResponse {
    fn validate(&self) -> R {
        finite3(&|| "gamma".into(), self.gamma)?;
        for (f, v) in [
            ("knee", self.knee),
            ("shoulder", self.shoulder),
            ("gain", self.gain),
            ("exposure_s", self.exposure_s),
            ("read_noise", self.read_noise),
            ("shot_noise", self.shot_noise),
        ] {
            finite(&|| f.into(), v as f64)?;
            if v < 0.0 {
                return fail(f, format!("{v} is negative"));
            }
        }
        if self.gamma.min_element() <= 0.0 || self.exposure_s <= 0.0 {
            return fail("gamma", "gamma and exposure must be positive");
        }
        if self.knee > 1.0 || self.shoulder <= 0.0 {
            return fail(
                "knee",
                "the knee lies in 0..=1 and the shoulder's slope is positive",
            );
        }
        if !(1..=16).contains(&self.bits) {
            return fail("bits", format!("{} is outside 1..=16", self.bits));
        }
        Ok(())
    }
}

impl Validate for CrtFace {
    fn validate(&self) -> R {
        resolution(&|| "width".into(), self.width, self.height)?;
        finite3(&|| "screen.origin".into(), self.screen.origin)?;
        finite3(&|| "screen.right".into(), self.screen.right)?;
        finite3(&|| "screen.down".into(), self.screen.down)?;
        if self.screen.right.cross(self.screen.down).length_squared() < 1e-12 {
            return fail("screen", "screen rectangle has zero area");
        }
        finite3(&|| "mirror.normal".into(), self.mirror.normal)?;
        finite(&|| "mirror.offset".into(), self.mirror.offset as f64)?;
        if (self.mirror.normal.length() - 1.0).abs() > 1e-3 {
            return fail("mirror.normal", "mirror normal is not unit length");
        }
        within(|| "photometry".into(), self.photometry.validate())
    }
}

impl Validate for CrtPhotometry {
    fn validate(&self) -> R {
        for (name, v) in [
            ("crt.gamma", self.crt.gamma),
            ("crt.peak", self.crt.peak),
            ("crt.black_level", self.crt.black_level),
            ("splitter.transmission", self.splitter.transmission),
            ("splitter.reflection", self.splitter.reflection),
        ] {
            finite3(&|| name.into(), v)?;
        }
        if self.crt.gamma.min_element() <= 0.0 {
            return fail("crt.gamma", "gamma must be positive");
        }
        if self.crt.peak.min_element() <= 0.0 {
            return fail("crt.peak", "peak radiance must be positive");
        }
        if self.crt.black_level.min_element() < 0.0 {
            return fail("crt.black_level", "black level must not be negative");
        }
        let t = self.splitter.transmission;
        if t.min_element() < 0.0 || t.max_element() > 1.0 {
            return fail("splitter.transmission", "transmission must lie in 0..=1");
        }
        let r = self.splitter.reflection;
        if r.min_element() <= 0.0 || r.max_element() > 1.0 {
            return fail("splitter.reflection", "reflection must lie in (0, 1]");
        }
        Ok(())
    }
}

impl Validate for Pose {
    fn validate(&self) -> R {
        finite3(&|| "position".into(), self.position)?;
        unit_quat(&|| "orientation".into(), self.orientation)
    }
}

/// Prefix the field of an error with `prefix.`.
fn within(prefix: impl FnOnce() -> String, r: R) -> R {
    r.map_err(|e| ValidationError {
        field: format!("{}.{}", prefix(), e.field),
        problem: e.problem,
    })
}

impl Validate for Showcase {
    fn validate(&self) -> R {
        let mut ids = HashSet::new();
        for (i, m) in self.meshes.iter().enumerate() {
            within(|| format!("meshes[{i}]"), m.mesh.validate())?;
            if m.id != m.mesh.id() {
                return fail(
                    format!("meshes[{i}].id"),
                    format!("content hash {} does not match the mesh data", m.id),
                );
            }
            ids.insert(m.id);
        }
        unique("objects", self.objects.iter().map(|o| o.name.as_str()))?;
        for (i, o) in self.objects.iter().enumerate() {
            name(&|| format!("objects[{i}].name"), &o.name)?;
            if !ids.contains(&o.mesh) {
                return fail(
                    format!("objects[{i}].mesh"),
                    format!("mesh {} is not in the snapshot", o.mesh),
                );
            }
            within(|| format!("objects[{i}].material"), o.material.validate())?;
            within(|| format!("objects[{i}].transform"), o.transform.validate())?;
        }
        unique("lights", self.lights.iter().map(|l| l.name.as_str()))?;
        for (i, l) in self.lights.iter().enumerate() {
            name(&|| format!("lights[{i}].name"), &l.name)?;
            within(|| format!("lights[{i}]"), l.light.validate())?;
        }
        unique(
            "projectors",
            self.projectors.iter().map(|p| p.name.as_str()),
        )?;
        for (i, p) in self.projectors.iter().enumerate() {
            name(&|| format!("projectors[{i}].name"), &p.name)?;
            within(|| format!("projectors[{i}].device"), p.device.validate())?;
            within(
                || format!("projectors[{i}].response"),
                p.response.validate(),
            )?;
        }
        unique("cameras", self.cameras.iter().map(|c| c.name.as_str()))?;
        for (i, c) in self.cameras.iter().enumerate() {
            name(&|| format!("cameras[{i}].name"), &c.name)?;
            within(|| format!("cameras[{i}].device"), c.device.validate())?;
            within(|| format!("cameras[{i}].response"), c.response.validate())?;
        }
        unique("faces", self.faces.iter().map(|f| f.name.as_str()))?;
        for (i, f) in self.faces.iter().enumerate() {
            name(&|| format!("faces[{i}].name"), &f.name)?;
            within(|| format!("faces[{i}]"), f.validate())?;
        }
        unique("observers", self.observers.iter().map(|o| o.name.as_str()))?;
        for (i, o) in self.observers.iter().enumerate() {
            name(&|| format!("observers[{i}].name"), &o.name)?;
            within(|| format!("observers[{i}].head"), o.head.validate())?;
            finite(&|| format!("observers[{i}].ipd"), o.ipd as f64)?;
            if !(0.0..=0.2).contains(&o.ipd) {
                return fail(
                    format!("observers[{i}].ipd"),
                    format!("{} m is outside 0..=0.2", o.ipd),
                );
            }
        }
        if let Some(a) = self.patch_area {
            finite(&|| "patch_area".into(), a)?;
            if !PATCH_AREA_RANGE.contains(&a) {
                return fail(
                    "patch_area",
                    format!(
                        "{a} m^2 is outside {:e}..={} m^2",
                        PATCH_AREA_RANGE.start(),
                        PATCH_AREA_RANGE.end()
                    ),
                );
            }
        }
        nonneg3(&|| "ambient".into(), self.ambient)
    }
}

impl Validate for FrameState {
    fn validate(&self) -> R {
        finite(&|| "time_s".into(), self.time_s)?;
        for (i, h) in self.heads.iter().enumerate() {
            within(|| format!("heads[{i}]"), h.validate())?;
        }
        for (i, l) in self.lights.iter().enumerate() {
            name(&|| format!("lights[{i}].name"), &l.name)?;
            within(|| format!("lights[{i}]"), l.light.validate())?;
        }
        for (i, t) in self.object_transforms.iter().enumerate() {
            within(
                || format!("object_transforms[{i}].transform"),
                t.transform.validate(),
            )?;
        }
        Ok(())
    }
}

impl FrameState {
    /// Check the indices of this frame against the scene it refers to.
    pub fn validate_against(&self, scene: &Showcase) -> R {
        self.validate()?;
        if self.heads.len() != scene.observers.len() {
            return fail(
                "heads",
                format!(
                    "{} head poses for {} observers",
                    self.heads.len(),
                    scene.observers.len()
                ),
            );
        }
        for (i, t) in self.object_transforms.iter().enumerate() {
            if t.object as usize >= scene.objects.len() {
                return fail(
                    format!("object_transforms[{i}].object"),
                    format!(
                        "object index {} is out of range for {} objects",
                        t.object,
                        scene.objects.len()
                    ),
                );
            }
        }
        Ok(())
    }
}

impl Validate for IlluminationMesh {
    fn validate(&self) -> R {
        finite(&|| "max_patch_area".into(), self.max_patch_area)?;
        if self.max_patch_area <= 0.0 {
            return fail("max_patch_area", "must be positive");
        }
        if self.element_depth > 6 {
            return fail(
                "element_depth",
                format!("{} is above the maximum of 6", self.element_depth),
            );
        }
        finite(&|| "min_element_area".into(), self.min_element_area)?;
        if self.min_element_area < 0.0 {
            return fail("min_element_area", "is negative");
        }
        Ok(())
    }
}

/// A solution value: finite, at most [`MAX_ILLUMINATION_VALUE`] in
/// magnitude.
fn illumination_value(field: &dyn Fn() -> String, v: &ElementLight) -> R {
    for x in v.channels() {
        finite(field, x as f64)?;
        if x.abs() > MAX_ILLUMINATION_VALUE {
            return fail(
                field(),
                format!("{x} W/m^2 is beyond {MAX_ILLUMINATION_VALUE}"),
            );
        }
    }
    Ok(())
}

fn too_many_elements(field: &str, n: usize) -> R {
    fail(
        field,
        format!("{n} elements is above the limit of {MAX_ILLUMINATION_ELEMENTS}"),
    )
}

/// The rules of a whole solution ([`IlluminationBody::Full`]), for the
/// master that publishes one as for the node that receives it.
pub(crate) fn full_solution(mesh: &IlluminationMesh, values: &[ElementLight]) -> R {
    within(|| "mesh".into(), mesh.validate())?;
    if values.len() > MAX_ILLUMINATION_ELEMENTS {
        return too_many_elements("values", values.len());
    }
    for (i, v) in values.iter().enumerate() {
        illumination_value(&|| format!("values[{i}]"), v)?;
    }
    Ok(())
}

impl Validate for IlluminationBody {
    fn validate(&self) -> R {
        match self {
            IlluminationBody::Full { mesh, values } => full_solution(mesh, values),
            IlluminationBody::Delta { changes, .. } => {
                if changes.len() > MAX_ILLUMINATION_ELEMENTS {
                    return too_many_elements("changes", changes.len());
                }
                let mut previous: Option<u32> = None;
                for (i, c) in changes.iter().enumerate() {
                    if previous.is_some_and(|p| c.element <= p) {
                        return fail(
                            format!("changes[{i}].element"),
                            format!(
                                "element {} after element {}: changes must be in increasing element order",
                                c.element,
                                previous.unwrap_or_default()
                            ),
                        );
                    }
                    previous = Some(c.element);
                    illumination_value(&|| format!("changes[{i}].value"), &c.value)?;
                }
                Ok(())
            }
        }
    }
}

impl Validate for Message {
    fn validate(&self) -> R {
        let kind = self.kind();
        let check = || -> R {
            match self {
                Message::Hello(Hello { node, .. }) => name(&|| "node".into(), node),
                Message::Welcome(Welcome {
                    target_hz,
                    deadline_ms,
                    ..
                }) => {
                    for (f, v) in [("target_hz", *target_hz), ("deadline_ms", *deadline_ms)] {
                        finite(&|| f.into(), v as f64)?;
                        if v <= 0.0 {
                            return fail(f, format!("{v} must be positive"));
                        }
                    }
                    Ok(())
                }
                Message::SceneSnapshot(s) => {
                    within(|| "showcase".into(), s.showcase.validate())?;
                    match &s.current {
                        Some(f) if f.scene_version != s.version => fail(
                            "current.scene_version",
                            format!(
                                "{} differs from snapshot version {}",
                                f.scene_version, s.version
                            ),
                        ),
                        Some(f) => within(|| "current".into(), f.validate_against(&s.showcase)),
                        None => Ok(()),
                    }?;
                    if s.maps.len() > crate::capture::MAX_MAPS {
                        return fail(
                            "maps",
                            format!(
                                "{} maps, at most {}",
                                s.maps.len(),
                                crate::capture::MAX_MAPS
                            ),
                        );
                    }
                    for (i, m) in s.maps.iter().enumerate() {
                        within(|| format!("maps[{i}]"), m.validate())?;
                    }
                    Ok(())
                }
                Message::FrameState(f) => f.validate(),
                Message::ShowPattern(p) => within(|| "pattern".into(), p.pattern.validate()),
                Message::CaptureFrames(c) => c.validate(),
                Message::FrameChunk(c) => c.validate(),
                Message::CaptureFailed(c) => c.validate(),
                Message::PatternShown(_) => Ok(()),
                Message::NodeStats(NodeStats {
                    render_ms,
                    barrier_wait_ms,
                    ..
                }) => {
                    for (f, v) in [
                        ("render_ms", *render_ms),
                        ("barrier_wait_ms", *barrier_wait_ms),
                    ] {
                        finite(&|| f.into(), v as f64)?;
                        if v < 0.0 {
                            return fail(f, format!("{v} is negative"));
                        }
                    }
                    Ok(())
                }
                Message::Bye(b) => {
                    if b.reason.len() > 4096 {
                        fail("reason", "longer than 4096 bytes")
                    } else {
                        Ok(())
                    }
                }
                Message::Illumination(i) => within(|| "body".into(), i.body.validate()),
                Message::Ready(_)
                | Message::Swap(_)
                | Message::ClockProbe(_)
                | Message::ClockReply(_)
                | Message::IlluminationResync(_)
                | Message::IlluminationReady(_) => Ok(()),
            }
        };
        within(|| kind.to_string(), check())
    }
}
