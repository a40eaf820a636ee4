//! Sparse form-factor rows (`(element, F)` sorted by element): a row
//! with its changed entries merged in, and the signed difference of two
//! rows, which is what a move shoots.

use crate::radiosity::shooting::ray_cast::{RayMask, UNKNOWN_RAYS};

/// The signed difference `new - old` of two rows sorted by element.
pub(super) fn row_difference(old: &[(u32, f64)], new: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let (mut a, mut b) = (old.iter().peekable(), new.iter().peekable());
    let mut out = Vec::new();
    loop {
        let d = match (a.peek(), b.peek()) {
            (Some(&&(ja, fa)), Some(&&(jb, fb))) => {
                if ja == jb {
                    a.next();
                    b.next();
                    (ja, fb - fa)
                } else if ja < jb {
                    a.next();
                    (ja, -fa)
                } else {
                    b.next();
                    (jb, fb)
                }
            }
            (Some(&&(ja, fa)), None) => {
                a.next();
                (ja, -fa)
            }
            (None, Some(&&(jb, fb))) => {
                b.next();
                (jb, fb)
            }
            (None, None) => break,
        };
        if d.1 != 0.0 {
            out.push(d);
        }
    }
    out
}

/// The signed difference `new - old` where `new` is `old` (sorted by
/// element) with `changes` (sorted) put in: as [`row_difference`] of the
/// merged row, touching only the changed entries.
pub(super) fn changes_difference(old: &[(u32, f64)], changes: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let mut rest = old;
    let mut out = Vec::with_capacity(changes.len());
    for &(j, f) in changes {
        let k = rest.partition_point(|e| e.0 < j);
        let before = match rest.get(k) {
            Some(&(jo, fo)) if jo == j => fo,
            _ => 0.0,
        };
        rest = &rest[k..];
        if f - before != 0.0 {
            out.push((j, f - before));
        }
    }
    out
}

/// `row` (sorted by element) with the entries of `changes` (sorted, a
/// zero value removes the entry) put in, and the rows' [`RayMask`]s
/// merged alike (`rays` aligned with `row`, `change_rays` with `changes`;
/// none when `row` has none).
pub(super) fn merge_changes(
    row: &[(u32, f64)],
    rays: Option<&[RayMask]>,
    changes: &[(u32, f64)],
    change_rays: &[RayMask],
) -> (Vec<(u32, f64)>, Option<Vec<RayMask>>) {
    let mut out = Vec::with_capacity(row.len() + changes.len());
    let mut out_rays = rays.map(|_| Vec::with_capacity(row.len() + changes.len()));
    let ray_of = |k: usize| rays.map_or(UNKNOWN_RAYS, |r| r[k]);
    let (mut a, mut c) = (0, 0);
    loop {
        let (next, mask) = match (row.get(a), changes.get(c)) {
            (Some(&(j, f)), Some(&(jc, fc))) => {
                if jc < j {
                    c += 1;
                    ((jc, fc), change_rays[c - 1])
                } else if jc == j {
                    a += 1;
                    c += 1;
                    ((jc, fc), change_rays[c - 1])
                } else {
                    a += 1;
                    ((j, f), ray_of(a - 1))
                }
            }
            (Some(&x), None) => {
                a += 1;
                (x, ray_of(a - 1))
            }
            (None, Some(&x)) => {
                c += 1;
                (x, change_rays[c - 1])
            }
            (None, None) => break,
        };
        if next.1 != 0.0 {
            out.push(next);
            if let Some(r) = out_rays.as_mut() {
                r.push(mask);
            }
        }
    }
    (out, out_rays)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_merge_and_difference_are_exact() {
        let old = [(1, 0.1), (3, 0.3), (5, 0.5)];
        let changes = [(0, 0.05), (3, 0.0), (5, 0.25), (7, 0.7)];
        // The rays' masks follow their entries; a removed entry drops its
        // mask, and a row without masks gets none.
        let (new, rays) = merge_changes(&old, Some(&[0b01, 0b11, 0b11]), &changes, &[1, 0, 2, 3]);
        assert_eq!(new, vec![(0, 0.05), (1, 0.1), (5, 0.25), (7, 0.7)]);
        assert_eq!(rays, Some(vec![1, 0b01, 2, 3]));
        assert_eq!(
            merge_changes(&old, None, &changes, &[1, 0, 2, 3]),
            (new.clone(), None)
        );
        let d = row_difference(&old, &new);
        assert_eq!(d, vec![(0, 0.05), (3, -0.3), (5, -0.25), (7, 0.7)]);
        assert_eq!(changes_difference(&old, &changes), d);
        assert!(changes_difference(&new, &[(1, 0.1), (5, 0.25)]).is_empty());
        assert!(row_difference(&new, &new).is_empty());
    }
}
