//! The cluster tree: a binary hierarchy over the active elements, split
//! at the median of the longest axis of their centres, one element per
//! leaf. Interior nodes are clusters (Smits, Arvo and Greenberg 1994):
//! a wall's elements merge into flat clusters that behave as one patch, a
//! scanned mesh's triangles into volume clusters.
//!
//! Objects that may move (`movers`) each get a subtree of their own: a
//! node whose members belong to more than one of them (or to one of them
//! and the static scene) is split between those first, so a move changes
//! the geometry of the mover's subtree and of its few ancestors only.

use crate::radiosity::mesh::RadiosityMesh;
use glam::DVec3;

/// No child / no element.
pub(super) const NONE: u32 = u32::MAX;

/// Member normals within this cosine of the mean normal make a node flat:
/// it receives one irradiance for all its members.
const FLAT_COS: f64 = 0.9999;

/// One node of the cluster tree.
#[derive(Clone, Debug)]
pub(super) struct Node {
    /// Area-weighted centroid of the members: about it the first-order
    /// variation of a far link's kernel cancels.
    pub center: DVec3,
    /// Radius of a sphere about `center` holding every member.
    pub radius: f64,
    /// Total surface area of the members (m^2).
    pub area: f64,
    /// Area-weighted mean unit normal (zero when the normals cancel).
    pub normal: DVec3,
    /// All members face `normal` (within [`FLAT_COS`]).
    pub flat: bool,
    /// Largest reflectance channel of any member.
    pub rho_max: f64,
    /// Members of more than one mover, or of a mover and the static
    /// scene: such a node changes when one of them moves, so it carries no
    /// link (it is always split).
    pub mixed: bool,
    /// 0 when every member is static, `k + 1` when all belong to mover
    /// `k`, [`NONE`] when mixed.
    pub group: u32,
    /// Children, or `[NONE, NONE]` for a leaf.
    pub children: [u32; 2],
    /// The element of a leaf, or `NONE`.
    pub element: u32,
    /// This node's members are `order[first..first + count]`.
    pub first: u32,
    /// Number of members.
    pub count: u32,
}

impl Node {
    pub(super) fn is_leaf(&self) -> bool {
        self.children[0] == NONE
    }
}

/// The tree; node 0 is the root, and every parent precedes its children.
#[derive(Clone, Debug, Default)]
pub(super) struct Tree {
    pub nodes: Vec<Node>,
    /// Elements in leaf order.
    pub order: Vec<u32>,
    /// The leaf node of each element (`NONE` when inactive).
    pub leaf_of: Vec<u32>,
    /// The root of each mover's subtree (`NONE` when it has no active
    /// element), in the order the movers were given.
    pub mover_roots: Vec<u32>,
}

impl Tree {
    /// The tree over the elements of `mesh` whose `active` entry is set,
    /// each object of `movers` in a subtree of its own.
    pub(super) fn build(mesh: &RadiosityMesh, active: &[bool], movers: &[u32]) -> Self {
        // 0 for the static scene, k + 1 for mover k.
        let group = |e: u32| {
            let object = mesh.elements[e as usize].object;
            movers
                .iter()
                .position(|&m| m == object)
                .map_or(0, |k| k as u32 + 1)
        };
        let mut order: Vec<u32> = (0..mesh.elements.len() as u32)
            .filter(|&e| active[e as usize] && mesh.elements[e as usize].area > 0.0)
            .collect();
        let mut tree = Tree {
            nodes: Vec::with_capacity(2 * order.len()),
            order: Vec::new(),
            leaf_of: vec![NONE; mesh.elements.len()],
            mover_roots: vec![NONE; movers.len()],
        };
        if order.is_empty() {
            return tree;
        }
        // Breadth of the work stack is the depth: O(log n) for median splits.
        tree.nodes.push(placeholder(0, order.len() as u32));
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let (first, count) = {
                let node = &tree.nodes[n as usize];
                (node.first as usize, node.count as usize)
            };
            let members = &mut order[first..first + count];
            let first_group = group(members[0]);
            let mixed = members.iter().any(|&e| group(e) != first_group);
            tree.nodes[n as usize].group = if mixed { NONE } else { first_group };
            if !mixed && first_group > 0 {
                let root = &mut tree.mover_roots[first_group as usize - 1];
                if *root == NONE {
                    *root = n;
                }
            }
            if count == 1 {
                tree.nodes[n as usize].element = members[0];
                tree.leaf_of[members[0] as usize] = n;
                continue;
            }
            if mixed {
                // The lowest group apart from the others.
                members.sort_unstable_by_key(|&e| (group(e), e));
                let lowest = group(members[0]);
                let half = members.iter().take_while(|&&e| group(e) == lowest).count();
                let left = tree.nodes.len() as u32;
                tree.nodes.push(placeholder(first as u32, half as u32));
                tree.nodes
                    .push(placeholder((first + half) as u32, (count - half) as u32));
                tree.nodes[n as usize].children = [left, left + 1];
                tree.nodes[n as usize].mixed = true;
                stack.push(left + 1);
                stack.push(left);
                continue;
            }
            let (lo, hi) = members.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), &e| {
                    let c = mesh.elements[e as usize].center;
                    (lo.min(c), hi.max(c))
                },
            );
            let extent = hi - lo;
            let axis = if extent.x >= extent.y && extent.x >= extent.z {
                0
            } else if extent.y >= extent.z {
                1
            } else {
                2
            };
            let half = count / 2;
            members.select_nth_unstable_by(half, |&a, &b| {
                let (ca, cb) = (
                    mesh.elements[a as usize].center[axis],
                    mesh.elements[b as usize].center[axis],
                );
                ca.total_cmp(&cb).then(a.cmp(&b))
            });
            let left = tree.nodes.len() as u32;
            tree.nodes.push(placeholder(first as u32, half as u32));
            tree.nodes
                .push(placeholder((first + half) as u32, (count - half) as u32));
            tree.nodes[n as usize].children = [left, left + 1];
            stack.push(left + 1);
            stack.push(left);
        }
        tree.order = order;
        tree.fill_geometry(mesh);
        tree
    }

    /// Bounds, areas, normals and flatness, bottom-up (again after a
    /// move).
    pub(super) fn fill_geometry(&mut self, mesh: &RadiosityMesh) {
        let mut bounds = vec![(DVec3::ZERO, DVec3::ZERO); self.nodes.len()];
        let mut weighted_normal = vec![DVec3::ZERO; self.nodes.len()];
        let mut weighted_center = vec![DVec3::ZERO; self.nodes.len()];
        for n in (0..self.nodes.len()).rev() {
            let node = &self.nodes[n];
            if node.is_leaf() {
                let e = &mesh.elements[node.element as usize];
                let lo = e.vertices[0].min(e.vertices[1]).min(e.vertices[2]);
                let hi = e.vertices[0].max(e.vertices[1]).max(e.vertices[2]);
                bounds[n] = (lo, hi);
                weighted_normal[n] = e.normal * e.area;
                weighted_center[n] = e.center * e.area;
                let node = &mut self.nodes[n];
                node.area = e.area;
                node.rho_max = e.reflectance.max_element();
            } else {
                let [a, b] = node.children.map(|c| c as usize);
                bounds[n] = (bounds[a].0.min(bounds[b].0), bounds[a].1.max(bounds[b].1));
                weighted_normal[n] = weighted_normal[a] + weighted_normal[b];
                weighted_center[n] = weighted_center[a] + weighted_center[b];
                let (area, rho) = (
                    self.nodes[a].area + self.nodes[b].area,
                    self.nodes[a].rho_max.max(self.nodes[b].rho_max),
                );
                let node = &mut self.nodes[n];
                node.area = area;
                node.rho_max = rho;
            }
            let (lo, hi) = bounds[n];
            let node = &mut self.nodes[n];
            node.center = weighted_center[n] / node.area;
            // The farthest corner of the box bounds the farthest member.
            let reach = (node.center - lo).abs().max((hi - node.center).abs());
            node.radius = reach.length();
            node.normal = weighted_normal[n].normalize_or_zero();
        }
        // Flat: every member within FLAT_COS of the node's normal.
        for n in 0..self.nodes.len() {
            let node = &self.nodes[n];
            let normal = node.normal;
            // A mixed node is never flat: a move would tilt it.
            let flat = !node.mixed
                && normal != DVec3::ZERO
                && self.order[node.first as usize..(node.first + node.count) as usize]
                    .iter()
                    .all(|&e| mesh.elements[e as usize].normal.dot(normal) >= FLAT_COS);
            self.nodes[n].flat = flat;
        }
    }

    /// The nodes of the subtree under `n`, `n` first.
    pub(super) fn subtree(&self, n: u32) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![n];
        while let Some(k) = stack.pop() {
            out.push(k);
            let node = &self.nodes[k as usize];
            if !node.is_leaf() {
                stack.extend(node.children);
            }
        }
        out
    }

    /// The members of node `n`.
    pub(super) fn members(&self, n: u32) -> &[u32] {
        let node = &self.nodes[n as usize];
        &self.order[node.first as usize..(node.first + node.count) as usize]
    }
}

fn placeholder(first: u32, count: u32) -> Node {
    Node {
        center: DVec3::ZERO,
        radius: 0.0,
        area: 0.0,
        normal: DVec3::ZERO,
        flat: false,
        rho_max: 0.0,
        mixed: false,
        group: 0,
        children: [NONE, NONE],
        element: NONE,
        first,
        count,
    }
}
