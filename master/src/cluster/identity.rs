//! Who may join the cluster. A connection is admitted only when three
//! things agree: the name its Hello claims, the names its certificate was
//! issued to (the TLS handshake already checked that the cluster CA signed
//! it), and an entry of the master's configuration with that name and
//! role. A certificate signed by the cluster CA is not enough on its own:
//! the CA may have issued certificates for machines that are not part of
//! this show.

use showcase_proto::Role;
use std::collections::BTreeMap;

/// The nodes the master admits: name and role, from the configuration.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Roster {
    nodes: BTreeMap<String, Role>,
}

/// Why a Hello was refused; its message names the claimed name, the
/// certificate's names and the configuration's entry.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "node {claimed:?} ({role}) refused: {problem}; its certificate is issued to {cert_names:?}; {}",
    match entry {
        Some(r) => format!("the configuration lists {claimed:?} as a {r}"),
        None => format!("the configuration lists only {listed:?}"),
    }
)]
pub struct Refusal {
    /// The name in the Hello.
    pub claimed: String,
    /// The role in the Hello.
    pub role: Role,
    /// The DNS names in the peer's certificate.
    pub cert_names: Vec<String>,
    /// The configuration's role for `claimed`, if it lists it.
    pub entry: Option<Role>,
    /// Every name the configuration lists (when `entry` is `None`).
    pub listed: Vec<String>,
    /// What disagrees.
    pub problem: &'static str,
}

impl Roster {
    /// A roster of these `(name, role)` entries.
    pub fn new(nodes: impl IntoIterator<Item = (String, Role)>) -> Self {
        Self {
            nodes: nodes.into_iter().collect(),
        }
    }

    /// The nodes of a cluster configuration.
    pub fn from_config(cfg: &showcase_proto::config::ClusterConfig) -> Self {
        Self::new(cfg.nodes.iter().map(|n| (n.name.clone(), n.role)))
    }

    /// Every `(name, role)` entry, by name.
    pub fn entries(&self) -> impl Iterator<Item = (&str, Role)> + '_ {
        self.nodes.iter().map(|(n, r)| (n.as_str(), *r))
    }

    /// Admit a Hello claiming `claimed` in `role` from a peer whose
    /// certificate is issued to `cert_names`; `cert_valid` says whether the
    /// certificate is valid for `claimed` (checked by webpki, which knows
    /// the matching rules).
    pub fn admit(
        &self,
        claimed: &str,
        role: Role,
        cert_names: &[String],
        cert_valid: bool,
    ) -> Result<(), Refusal> {
        let entry = self.nodes.get(claimed).copied();
        let problem = match entry {
            None => "the configuration lists no node of that name",
            Some(r) if r != role => "the configuration gives that node another role",
            Some(_) if !cert_valid => "its certificate is not issued to that name",
            Some(_) => return Ok(()),
        };
        Err(Refusal {
            claimed: claimed.to_owned(),
            role,
            cert_names: cert_names.to_vec(),
            entry,
            listed: self.nodes.keys().cloned().collect(),
            problem,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roster() -> Roster {
        Roster::new([
            ("face-0".to_owned(), Role::Face),
            ("projector-0".to_owned(), Role::Projector),
        ])
    }

    #[test]
    fn admits_only_when_name_certificate_and_entry_agree() {
        let r = roster();
        let names = |n: &str| vec![n.to_owned()];
        assert_eq!(
            r.admit("face-0", Role::Face, &names("face-0"), true),
            Ok(())
        );

        let e = r
            .admit("intruder", Role::Face, &names("intruder"), true)
            .unwrap_err();
        assert_eq!(e.entry, None);
        assert_eq!(
            e.to_string(),
            "node \"intruder\" (face) refused: the configuration lists no node of that name; \
             its certificate is issued to [\"intruder\"]; the configuration lists only \
             [\"face-0\", \"projector-0\"]"
        );

        let e = r
            .admit("face-0", Role::Face, &names("projector-0"), false)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "node \"face-0\" (face) refused: its certificate is not issued to that name; \
             its certificate is issued to [\"projector-0\"]; the configuration lists \
             \"face-0\" as a face"
        );

        let e = r
            .admit("face-0", Role::Projector, &names("face-0"), true)
            .unwrap_err();
        assert!(e.to_string().contains("another role"), "{e}");
        assert_eq!(e.entry, Some(Role::Face));
    }
}
