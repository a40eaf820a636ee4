//! Where the fragment shaders read their per-frame arrays (light samples,
//! eyes, shadow views, albedos) from. llvmpipe (lavapipe, Mesa 22) loads
//! a storage buffer lane by lane with a bounds check per lane, so those
//! loads were most of the irradiance map's and the face view's time; a
//! uniform array is read as plain memory. The shaders therefore declare
//! each such binding as a uniform array of fixed capacity
//! (`var<uniform> NAME: array<T, N>;`), and a frame whose arrays exceed a
//! capacity uses the storage variant of the same source, made by
//! [`ArraySpace::source`], with the same results.

use std::borrow::Cow;

/// The address space of a shader's per-frame arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ArraySpace {
    /// Uniform arrays of the capacity the shader declares (the fast path).
    Uniform,
    /// Runtime-sized read-only storage arrays (any length).
    Storage,
}

/// The capacity `N` of the uniform array binding `var<uniform> name:
/// array<T, N>;` in `wgsl`, or `None` when there is no such declaration.
pub fn uniform_capacity(wgsl: &str, name: &str) -> Option<usize> {
    wgsl.lines().find_map(|line| {
        let rest = line.split("var<uniform>").nth(1)?.trim_start();
        let rest = rest.strip_prefix(name)?.trim_start().strip_prefix(':')?;
        let inner = rest.trim().strip_prefix("array<")?;
        let (_, n) = inner.split_once(',')?;
        n.trim()
            .trim_end_matches(';')
            .trim_end_matches('>')
            .trim()
            .trim_end_matches(['u', 'i'])
            .parse()
            .ok()
    })
}

impl ArraySpace {
    /// [`Self::Uniform`] when every `(length, name)` array fits the
    /// capacity `wgsl` declares for `name`, else [`Self::Storage`].
    pub fn for_lengths(wgsl: &str, lengths: &[(usize, &str)]) -> Self {
        let fits = lengths
            .iter()
            .all(|&(len, name)| uniform_capacity(wgsl, name).is_some_and(|cap| len <= cap));
        if fits { Self::Uniform } else { Self::Storage }
    }

    /// `wgsl` for this space: unchanged for [`Self::Uniform`]; for
    /// [`Self::Storage`] every `var<uniform> NAME: array<T, N>;` becomes
    /// `var<storage, read> NAME: array<T>;` (other declarations unchanged).
    pub fn source(self, wgsl: &str) -> Cow<'_, str> {
        if self == Self::Uniform {
            return Cow::Borrowed(wgsl);
        }
        let mut out = String::with_capacity(wgsl.len());
        for line in wgsl.lines() {
            match line.split_once("var<uniform>") {
                Some((head, rest)) if rest.contains(": array<") => {
                    let (decl, array) = rest.split_once(": array<").unwrap_or((rest, ""));
                    let element = array.split(',').next().unwrap_or("").trim();
                    out.push_str(&format!(
                        "{head}var<storage, read>{decl}: array<{element}>;"
                    ));
                }
                _ => out.push_str(line),
            }
            out.push('\n');
        }
        Cow::Owned(out)
    }

    /// The bind group layout type of a per-frame array binding.
    pub fn binding_type(self) -> wgpu::BindingType {
        wgpu::BindingType::Buffer {
            ty: match self {
                Self::Uniform => wgpu::BufferBindingType::Uniform,
                Self::Storage => wgpu::BufferBindingType::Storage { read_only: true },
            },
            has_dynamic_offset: false,
            min_binding_size: None,
        }
    }
}

/// The buffer usages of a per-frame array buffer (bindable in either
/// space).
pub const ARRAY_USAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::UNIFORM.union(wgpu::BufferUsages::STORAGE);

#[cfg(test)]
mod tests {
    use super::*;

    const SOURCE: &str = "struct S { a: vec4<f32>, }\n\
        @group(0) @binding(0) var<uniform> frame: S;\n\
        @group(0) @binding(1) var<uniform> lights: array<S, 64>;\n\
        @group(0) @binding(2) var<uniform> views : array<S, 512u>;\n";

    #[test]
    fn capacities_are_read_from_the_declarations() {
        assert_eq!(uniform_capacity(SOURCE, "lights"), Some(64));
        assert_eq!(uniform_capacity(SOURCE, "views"), Some(512));
        assert_eq!(uniform_capacity(SOURCE, "frame"), None);
        assert_eq!(uniform_capacity(SOURCE, "eyes"), None);
    }

    #[test]
    fn the_space_is_storage_only_when_an_array_overflows_or_is_unknown() {
        assert_eq!(
            ArraySpace::for_lengths(SOURCE, &[(64, "lights"), (0, "views")]),
            ArraySpace::Uniform
        );
        assert_eq!(
            ArraySpace::for_lengths(SOURCE, &[(65, "lights"), (0, "views")]),
            ArraySpace::Storage
        );
        assert_eq!(
            ArraySpace::for_lengths(SOURCE, &[(1, "eyes")]),
            ArraySpace::Storage
        );
    }

    #[test]
    fn the_storage_source_declares_runtime_sized_arrays_and_validates() {
        let s = ArraySpace::Storage.source(SOURCE);
        assert!(s.contains("var<storage, read> lights: array<S>;"), "{s}");
        assert!(s.contains("var<storage, read> views : array<S>;"), "{s}");
        assert!(s.contains("var<uniform> frame: S;"), "{s}");
        for src in [SOURCE, &s] {
            let module = naga::front::wgsl::parse_str(src).expect("parses");
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::default(),
            )
            .validate(&module)
            .expect("validates");
        }
        assert_eq!(ArraySpace::Uniform.source(SOURCE), SOURCE);
    }
}
