//! Meshes by content hash: the triangle data every object refers to, and
//! the entry that carries a mesh inline in a snapshot.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Content hash of a [`Mesh`] (BLAKE3 over its canonical little-endian bytes).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct MeshId(pub [u8; 32]);

impl fmt::Display for MeshId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in &self.0[..8] {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for MeshId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MeshId({self})")
    }
}

/// An indexed triangle mesh in object space. Triangles wind counter-clockwise
/// seen from the side their normal points to.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex normals: empty (use face normals) or one per position.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates: empty or one per position.
    pub uvs: Vec<Vec2>,
    /// Triangles as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// The content hash that names this mesh on the wire and in caches.
    pub fn id(&self) -> MeshId {
        let mut h = blake3::Hasher::new();
        h.update(&(self.positions.len() as u64).to_le_bytes());
        for p in &self.positions {
            for c in p.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.normals.len() as u64).to_le_bytes());
        for n in &self.normals {
            for c in n.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.uvs.len() as u64).to_le_bytes());
        for t in &self.uvs {
            for c in t.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.triangles.len() as u64).to_le_bytes());
        for t in &self.triangles {
            for i in t {
                h.update(&i.to_le_bytes());
            }
        }
        MeshId(*h.finalize().as_bytes())
    }

    /// Axis-aligned bounds `(min, max)`; `None` for a mesh with no vertices.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Total surface area of all triangles.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}

/// A mesh with its content hash, as carried inline in a snapshot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshEntry {
    /// Must equal `mesh.id()`; checked on validation.
    pub id: MeshId,
    /// The mesh data.
    pub mesh: Mesh,
}

impl MeshEntry {
    /// Wrap a mesh with its computed content hash.
    pub fn new(mesh: Mesh) -> Self {
        Self {
            id: mesh.id(),
            mesh,
        }
    }
}
