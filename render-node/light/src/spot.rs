//! The cone of a spot light: how a cone given in degrees is read and how
//! intensity falls off from its axis. The frame model (and so every CPU
//! reference and GPU upload) and the radiosity sources share this one
//! rule; the GPU's `shadow_lookup.part.wgsl` mirrors [`spot_falloff`].

/// Cosines `(cos_inner, cos_outer)` of a cone given as half-angles in
/// degrees, as `showcase_proto::Light::Spot` states it. The outer angle is
/// clamped to `[0, 180]` and the inner one to `[0, outer]`, so an inner
/// angle past the outer one is a hard edge at the outer one. A NaN inner
/// angle reads as the outer one (a hard edge); a NaN outer angle stays NaN,
/// which [`spot_falloff`] turns into no light.
pub fn cone_cosines(inner_deg: f64, outer_deg: f64) -> (f64, f64) {
    let outer = outer_deg.clamp(0.0, 180.0);
    // `min` keeps `outer` when the inner angle is NaN.
    let inner = inner_deg.clamp(0.0, 180.0).min(outer);
    (inner.to_radians().cos(), outer.to_radians().cos())
}

/// Smoothstep from the outer to the inner cone, by the cosine of the angle
/// from the axis: 0 at or outside `cos_outer` (and for a NaN cosine), 1 at
/// or inside `cos_inner`. When the cone has no soft band
/// (`cos_inner <= cos_outer`, or NaN) the edge is hard and the outer
/// boundary wins: 0 at exactly `cos_outer`, 1 inside it, which is the limit
/// of the smooth case as the band closes.
pub fn spot_falloff(cos_angle: f64, cos_inner: f64, cos_outer: f64) -> f64 {
    if !(cos_angle > cos_outer) {
        return 0.0;
    }
    let width = cos_inner - cos_outer;
    if !(width > 0.0) {
        return 1.0;
    }
    let t = ((cos_angle - cos_outer) / width).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_falloff_edges() {
        let (ci, co) = (0.9, 0.8);
        assert_eq!(spot_falloff(0.8, ci, co), 0.0);
        assert_eq!(spot_falloff(0.95, ci, co), 1.0);
        assert!((spot_falloff(0.85, ci, co) - 0.5).abs() < 1e-12);
        assert_eq!(spot_falloff(f64::NAN, ci, co), 0.0);
        assert_eq!(spot_falloff(0.81, 0.8, 0.8), 1.0, "hard edge");
    }

    /// The falloff of a cone given in degrees.
    fn falloff_deg(cos_axis: f64, inner_deg: f64, outer_deg: f64) -> f64 {
        let (ci, co) = cone_cosines(inner_deg, outer_deg);
        spot_falloff(cos_axis, ci, co)
    }

    #[test]
    fn spot_falloff_is_smooth_and_bounded() {
        assert_eq!(falloff_deg(1.0, 10.0, 20.0), 1.0);
        assert_eq!(falloff_deg(0.0, 10.0, 20.0), 0.0);
        let mid = falloff_deg(15f64.to_radians().cos(), 10.0, 20.0);
        assert!(mid > 0.3 && mid < 0.7, "{mid}");
        assert_eq!(falloff_deg(0.99, f64::NAN, 20.0), 1.0);
    }

    #[test]
    fn cone_degrees_are_clamped_and_a_reversed_cone_has_a_hard_edge() {
        let cos = |d: f64| d.to_radians().cos();
        assert_eq!(cone_cosines(10.0, 20.0), (cos(10.0), cos(20.0)));
        assert_eq!(cone_cosines(30.0, 20.0), (cos(20.0), cos(20.0)));
        assert_eq!(cone_cosines(-5.0, 200.0), (1.0, cos(180.0)));
        assert_eq!(falloff_deg(cos(25.0), 30.0, 20.0), 0.0);
        assert_eq!(falloff_deg(cos(15.0), 30.0, 20.0), 1.0);
        // Exactly on a hard edge: the outer boundary wins.
        assert_eq!(falloff_deg(cos(20.0), 20.0, 20.0), 0.0);
        let (ci, co) = cone_cosines(10.0, f64::NAN);
        assert_eq!(ci, cos(10.0));
        assert_eq!(spot_falloff(1.0, ci, co), 0.0);
    }
}
