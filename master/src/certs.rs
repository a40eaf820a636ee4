//! The cluster's certificate authority: `showcase-master certs` makes a CA
//! and one certificate per peer, signed by it. Peers are named by DNS-style
//! names that go into the certificates' subject alternative names; the
//! master's certificate carries [`MASTER_SERVER_NAME`].

use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa,
    KeyPair, KeyUsagePurpose,
};
use std::path::{Path, PathBuf};

pub use showcase_render::net::MASTER_SERVER_NAME;
/// File stem of the master's certificate and key.
pub const MASTER_FILE: &str = "master";

/// Why certificates could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum CertError {
    /// A node name cannot be a certificate subject name.
    #[error("node name {0:?} is not a valid DNS-style name (letters, digits, '-', '.')")]
    BadName(String),
    /// The same node name was given twice.
    #[error("node name {0:?} is given twice")]
    Duplicate(String),
    /// rcgen failed.
    #[error("certificate generation: {0}")]
    Generate(#[from] rcgen::Error),
    /// A file could not be written.
    #[error("{path}: {error}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The IO error.
        error: std::io::Error,
    },
}

/// A certificate and its private key, PEM encoded.
#[derive(Debug, Clone)]
pub struct PeerCert {
    /// File stem and subject name.
    pub name: String,
    /// The certificate (PEM).
    pub cert_pem: String,
    /// The private key (PEM).
    pub key_pem: String,
}

/// A freshly made cluster CA with the master's and the nodes' certificates.
#[derive(Debug, Clone)]
pub struct ClusterCerts {
    /// The CA certificate (PEM).
    pub ca_pem: String,
    /// The CA key (PEM); keep it offline after issuing.
    pub ca_key_pem: String,
    /// The master first, then one entry per node.
    pub peers: Vec<PeerCert>,
}

fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 63
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '.')
        && !name.starts_with(['-', '.'])
        && !name.ends_with(['-', '.'])
}

/// Make a cluster CA, a certificate for the master and one per node.
pub fn generate(nodes: &[String]) -> Result<ClusterCerts, CertError> {
    let mut seen = std::collections::HashSet::new();
    for n in nodes {
        if !valid_name(n) || n == MASTER_FILE || n == "ca" {
            return Err(CertError::BadName(n.clone()));
        }
        if !seen.insert(n) {
            return Err(CertError::Duplicate(n.clone()));
        }
    }
    let mut ca_params = CertificateParams::new(Vec::<String>::new())?;
    ca_params
        .distinguished_name
        .push(DnType::CommonName, "Showcase cluster CA");
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca_params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    let ca_key = KeyPair::generate()?;
    let ca_key_pem = ca_key.serialize_pem();
    let ca = CertifiedIssuer::self_signed(ca_params, ca_key)?;

    let issue = |name: &str, sans: Vec<String>| -> Result<PeerCert, CertError> {
        let mut params = CertificateParams::new(sans)?;
        params.distinguished_name.push(DnType::CommonName, name);
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        let key = KeyPair::generate()?;
        let cert = params.signed_by(&key, &ca)?;
        Ok(PeerCert {
            name: name.to_owned(),
            cert_pem: cert.pem(),
            key_pem: key.serialize_pem(),
        })
    };
    let mut peers = vec![issue(
        MASTER_FILE,
        vec![MASTER_SERVER_NAME.to_owned(), "localhost".to_owned()],
    )?];
    for n in nodes {
        peers.push(issue(n, vec![n.clone()])?);
    }
    Ok(ClusterCerts {
        ca_pem: ca.pem(),
        ca_key_pem,
        peers,
    })
}

fn write_file(path: PathBuf, text: &str, secret: bool) -> Result<PathBuf, CertError> {
    let err = |error| CertError::Write {
        path: path.clone(),
        error,
    };
    std::fs::write(&path, text).map_err(err)?;
    #[cfg(unix)]
    if secret {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).map_err(err)?;
    }
    #[cfg(not(unix))]
    let _ = secret;
    Ok(path)
}

/// Write `ca.pem`, `ca.key`, and `<name>.pem`/`<name>.key` per peer into
/// `dir` (created if missing); keys are readable by the owner only.
pub fn write(dir: &Path, certs: &ClusterCerts) -> Result<Vec<PathBuf>, CertError> {
    std::fs::create_dir_all(dir).map_err(|error| CertError::Write {
        path: dir.to_owned(),
        error,
    })?;
    let mut files = vec![
        write_file(dir.join("ca.pem"), &certs.ca_pem, false)?,
        write_file(dir.join("ca.key"), &certs.ca_key_pem, true)?,
    ];
    for p in &certs.peers {
        files.push(write_file(
            dir.join(format!("{}.pem", p.name)),
            &p.cert_pem,
            false,
        )?);
        files.push(write_file(
            dir.join(format!("{}.key", p.name)),
            &p.key_pem,
            true,
        )?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        for bad in ["", "-x", "a b", "ca", "master", "x.", "ünï"] {
            let err = generate(&[bad.to_owned()]).unwrap_err();
            assert!(matches!(err, CertError::BadName(_)), "{bad}: {err}");
        }
        let err = generate(&["a".into(), "a".into()]).unwrap_err();
        assert_eq!(err.to_string(), "node name \"a\" is given twice");
    }

    #[test]
    fn writes_every_file() {
        let dir = std::env::temp_dir().join(format!("showcase-certs-{}", std::process::id()));
        let certs = generate(&["face-0".into(), "projector-1".into()]).unwrap();
        let files = write(&dir, &certs).unwrap();
        assert_eq!(files.len(), 2 + 2 * 3);
        for f in &files {
            let text = std::fs::read_to_string(f).unwrap();
            assert!(text.starts_with("-----BEGIN"), "{}", f.display());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
