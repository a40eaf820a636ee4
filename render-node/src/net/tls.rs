//! Mutual TLS for the cluster. Every peer holds a certificate signed by the
//! cluster CA (`showcase-master certs`); the master requires and verifies
//! client certificates, and a node verifies the master's. Node names are
//! DNS names in their certificates, so the master can check that a Hello
//! comes from the node it claims to be.

use quinn::crypto::rustls::{QuicClientConfig, QuicServerConfig};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName, UnixTime};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The name nodes expect in the master's certificate.
pub const MASTER_SERVER_NAME: &str = "showcase-master";

/// ALPN protocol identifier of the cluster protocol.
pub const ALPN: &[u8] = b"showcase/1";

/// Why TLS material could not be loaded or used.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A PEM file is missing or unreadable.
    #[error("{path}: {problem}")]
    Pem {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// rustls refused the configuration.
    #[error("tls configuration: {0}")]
    Config(String),
}

/// Why a peer's certificate will not be accepted, and what to do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{problem}; {fix}")]
pub struct CertProblem {
    /// What is wrong.
    pub problem: String,
    /// What to do.
    pub fix: String,
    /// The fix is to re-issue the certificates (a caller that knows the
    /// nodes can give the exact `showcase-master certs` command).
    pub reissue: bool,
}

/// A peer's certificate chain and key plus the cluster CA that it trusts.
#[derive(Debug)]
pub struct ClusterIdentity {
    /// The cluster CA certificate.
    pub ca: CertificateDer<'static>,
    /// The peer's certificate chain (leaf first).
    pub chain: Vec<CertificateDer<'static>>,
    /// The peer's private key.
    pub key: PrivateKeyDer<'static>,
}

impl Clone for ClusterIdentity {
    fn clone(&self) -> Self {
        Self {
            ca: self.ca.clone(),
            chain: self.chain.clone(),
            key: self.key.clone_key(),
        }
    }
}

/// A PEM file that could not be read: a missing one says how to make it.
fn read_err(path: &Path, e: rustls::pki_types::pem::Error) -> TlsError {
    match e {
        rustls::pki_types::pem::Error::Io(io) if io.kind() == std::io::ErrorKind::NotFound => {
            let dir = path.parent().unwrap_or(Path::new("."));
            pem_err(
                path,
                format!(
                    "missing; make the cluster's certificates with `showcase-master certs --out {} \
                     --node NAME ...` (one --node per [[node]] of the cluster config)",
                    dir.display()
                ),
            )
        }
        other => pem_err(path, other),
    }
}

fn pem_err(path: &Path, e: impl std::fmt::Display) -> TlsError {
    TlsError::Pem {
        path: path.to_owned(),
        problem: e.to_string(),
    }
}

impl ClusterIdentity {
    /// Load `ca.pem`, `<name>.pem` and `<name>.key` from `dir`, as written
    /// by `showcase-master certs`. A missing file is named with the command
    /// that makes it.
    pub fn load(dir: &Path, name: &str) -> Result<Self, TlsError> {
        let ca_path = dir.join("ca.pem");
        let ca = CertificateDer::from_pem_file(&ca_path).map_err(|e| read_err(&ca_path, e))?;
        let cert_path = dir.join(format!("{name}.pem"));
        let chain = CertificateDer::pem_file_iter(&cert_path)
            .map_err(|e| read_err(&cert_path, e))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| read_err(&cert_path, e))?;
        if chain.is_empty() {
            return Err(pem_err(&cert_path, "no certificate in file"));
        }
        let key_path = dir.join(format!("{name}.key"));
        let key = PrivateKeyDer::from_pem_file(&key_path).map_err(|e| read_err(&key_path, e))?;
        Ok(Self { ca, chain, key })
    }

    /// Check that the leaf certificate is signed by the cluster CA, valid at
    /// `now` and issued to `name`, for a server (the master) or a client (a
    /// node): what the peers' TLS handshakes and the master's roster will
    /// require.
    pub fn verify(&self, name: &str, server: bool, now: UnixTime) -> Result<(), CertProblem> {
        const REISSUE: &str = "re-issue the cluster's certificates with `showcase-master certs` \
                               and copy ca.pem and each peer's files to its PC";
        let bad = |problem: String, fix: &str| CertProblem {
            problem,
            fix: fix.to_owned(),
            reissue: fix == REISSUE,
        };
        let leaf = self
            .chain
            .first()
            .ok_or_else(|| bad("no certificate in the file".into(), REISSUE))?;
        let cert = webpki::EndEntityCert::try_from(leaf).map_err(|e| {
            bad(
                format!("not a certificate this cluster can use ({e})"),
                REISSUE,
            )
        })?;
        let anchor = webpki::anchor_from_trusted_cert(&self.ca)
            .map_err(|e| bad(format!("ca.pem is not a CA certificate ({e})"), REISSUE))?;
        let usage = if server {
            webpki::KeyUsage::server_auth()
        } else {
            webpki::KeyUsage::client_auth()
        };
        cert.verify_for_usage(
            webpki::ALL_VERIFICATION_ALGS,
            &[anchor],
            &self.chain[1..],
            now,
            usage,
            None,
            None,
        )
        .map_err(|e| match e {
            webpki::Error::UnknownIssuer | webpki::Error::InvalidSignatureForPublicKey => bad(
                "not signed by the cluster CA in ca.pem (another CA issued it)".into(),
                REISSUE,
            ),
            webpki::Error::CertExpired { time, not_after } => bad(
                format!(
                    "expired {} days ago",
                    time.as_secs().saturating_sub(not_after.as_secs()) / 86_400
                ),
                REISSUE,
            ),
            webpki::Error::CertNotValidYet { time, not_before } => bad(
                format!(
                    "not valid for another {} s",
                    not_before.as_secs().saturating_sub(time.as_secs())
                ),
                "check this PC's clock",
            ),
            other => bad(format!("rejected against ca.pem ({other})"), REISSUE),
        })?;
        let server_name = ServerName::try_from(name.to_owned()).map_err(|_| {
            bad(
                format!("{name:?} is not a DNS-style certificate name"),
                "rename the node: letters, digits, '-' and '.'",
            )
        })?;
        cert.verify_is_valid_for_subject_name(&server_name)
            .map_err(|_| {
                bad(
                    format!(
                        "issued to {:?}, not to {name:?}",
                        cert.valid_dns_names().collect::<Vec<_>>()
                    ),
                    &format!("put the certificate issued to {name:?} here, or {REISSUE}"),
                )
            })
    }

    /// Build from PEM text (certificates generated in memory, e.g. tests).
    pub fn from_pem(ca: &str, chain: &str, key: &str) -> Result<Self, TlsError> {
        let here = Path::new("<memory>");
        Ok(Self {
            ca: CertificateDer::from_pem_slice(ca.as_bytes()).map_err(|e| pem_err(here, e))?,
            chain: CertificateDer::pem_slice_iter(chain.as_bytes())
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| pem_err(here, e))?,
            key: PrivateKeyDer::from_pem_slice(key.as_bytes()).map_err(|e| pem_err(here, e))?,
        })
    }

    fn roots(&self) -> Result<Arc<rustls::RootCertStore>, TlsError> {
        let mut roots = rustls::RootCertStore::empty();
        roots
            .add(self.ca.clone())
            .map_err(|e| TlsError::Config(format!("cluster CA: {e}")))?;
        Ok(Arc::new(roots))
    }
}

fn provider() -> Arc<rustls::crypto::CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

/// The master's QUIC server configuration: requires a client certificate
/// signed by the cluster CA.
pub fn server_config(id: &ClusterIdentity) -> Result<quinn::ServerConfig, TlsError> {
    let verifier =
        rustls::server::WebPkiClientVerifier::builder_with_provider(id.roots()?, provider())
            .build()
            .map_err(|e| TlsError::Config(e.to_string()))?;
    let mut tls = rustls::ServerConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| TlsError::Config(e.to_string()))?
        .with_client_cert_verifier(verifier)
        .with_single_cert(id.chain.clone(), id.key.clone_key())
        .map_err(|e| TlsError::Config(e.to_string()))?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    let quic = QuicServerConfig::try_from(tls).map_err(|e| TlsError::Config(e.to_string()))?;
    let mut cfg = quinn::ServerConfig::with_crypto(Arc::new(quic));
    cfg.transport_config(transport());
    Ok(cfg)
}

/// A node's QUIC client configuration: trusts only the cluster CA and
/// presents the node's certificate.
pub fn client_config(id: &ClusterIdentity) -> Result<quinn::ClientConfig, TlsError> {
    let mut tls = rustls::ClientConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| TlsError::Config(e.to_string()))?
        .with_root_certificates(id.roots()?)
        .with_client_auth_cert(id.chain.clone(), id.key.clone_key())
        .map_err(|e| TlsError::Config(e.to_string()))?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    let quic = QuicClientConfig::try_from(tls).map_err(|e| TlsError::Config(e.to_string()))?;
    let mut cfg = quinn::ClientConfig::new(Arc::new(quic));
    cfg.transport_config(transport());
    Ok(cfg)
}

/// The master endpoint's settings: its stateless-reset key and the key of
/// its connection-id generator are derived from the master's private key.
/// A master restarted with the same identity so recognises the old
/// connections' ids as its own and answers their packets with resets the
/// nodes accept: they notice the restart at their next keep-alive instead
/// of waiting out the idle timeout. (With quinn's random keys the new
/// master drops those packets as invalid ids.)
pub fn server_endpoint_config(id: &ClusterIdentity) -> quinn::EndpointConfig {
    let derive = |label: &[u8]| {
        let mut ctx = ring::digest::Context::new(&ring::digest::SHA256);
        ctx.update(label);
        ctx.update(id.key.secret_der());
        ctx.finish()
    };
    let reset = derive(b"showcase stateless reset key\0");
    let key = ring::hmac::Key::new(ring::hmac::HMAC_SHA256, reset.as_ref());
    let mut cfg = quinn::EndpointConfig::new(Arc::new(key));
    let cid = derive(b"showcase connection id key\0");
    let cid_key = u64::from_le_bytes(cid.as_ref()[..8].try_into().expect("SHA-256 has 32 bytes"));
    cfg.cid_generator(move || {
        Box::new(quinn_proto::HashedConnectionIdGenerator::from_key(cid_key))
    });
    cfg
}

/// Keep-alive interval on every cluster connection: with the reset key
/// above it bounds how long a node takes to notice a restarted master.
pub const KEEP_ALIVE: std::time::Duration = std::time::Duration::from_millis(100);

/// Idle timeout: a master or node that vanished without a restart is given
/// up after this long.
pub const IDLE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(3);

fn transport() -> Arc<quinn::TransportConfig> {
    let mut t = quinn::TransportConfig::default();
    // Frame-lock traffic is tiny and latency-bound; detect dead peers fast.
    t.keep_alive_interval(Some(KEEP_ALIVE));
    t.max_idle_timeout(Some(
        IDLE_TIMEOUT
            .try_into()
            .expect("3 s is a valid idle timeout"),
    ));
    // The cluster is one LAN: start from a LAN round trip, so a dial that
    // races a (re)starting master retries its Initial within tens of
    // milliseconds instead of quinn's default second.
    t.initial_rtt(std::time::Duration::from_millis(10));
    Arc::new(t)
}

/// The DNS names the peer of `conn` presented in its certificate (for log
/// lines; use [`peer_is`] to decide).
pub fn peer_names(conn: &quinn::Connection) -> Vec<String> {
    let Some(identity) = conn.peer_identity() else {
        return Vec::new();
    };
    let Ok(chain) = identity.downcast::<Vec<CertificateDer<'static>>>() else {
        return Vec::new();
    };
    let Some(leaf) = chain.first() else {
        return Vec::new();
    };
    webpki::EndEntityCert::try_from(leaf)
        .map(|c| c.valid_dns_names().map(str::to_owned).collect())
        .unwrap_or_default()
}

/// True when the peer of `conn` presented a certificate valid for `name`
/// (its node name). The chain itself was already verified by the handshake.
pub fn peer_is(conn: &quinn::Connection, name: &str) -> bool {
    let Some(identity) = conn.peer_identity() else {
        return false;
    };
    let Ok(chain) = identity.downcast::<Vec<CertificateDer<'static>>>() else {
        return false;
    };
    let Some(leaf) = chain.first() else {
        return false;
    };
    let Ok(server_name) = ServerName::try_from(name.to_owned()) else {
        return false;
    };
    webpki::EndEntityCert::try_from(leaf)
        .and_then(|c| c.verify_is_valid_for_subject_name(&server_name))
        .is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The error `run` and `showcase-node` stop with when the certificates
    /// were never made names the file and the command that makes it.
    #[test]
    fn a_missing_ca_names_the_file_and_the_certs_command() {
        let dir = std::env::temp_dir().join(format!("showcase-no-certs-{}", std::process::id()));
        let err = ClusterIdentity::load(&dir, "face-0")
            .unwrap_err()
            .to_string();
        let ca = dir.join("ca.pem");
        assert!(
            err.starts_with(&format!("{}: missing;", ca.display())),
            "{err}"
        );
        assert!(
            err.contains(&format!("`showcase-master certs --out {}", dir.display())),
            "{err}"
        );
        assert!(!err.contains("I/O error"), "{err}");
    }
}
