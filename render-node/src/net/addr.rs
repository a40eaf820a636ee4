//! Resolving the configuration's `HOST:PORT` addresses ([`HostPort`]) where
//! they are used: the master's listen address, a node's bind address and
//! the master a node dials. Proto checks only their syntax (it does no IO).

use showcase_proto::config::HostPort;
use std::net::{SocketAddr, ToSocketAddrs};

/// An address whose host name does not resolve.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{}: cannot resolve host {host:?} ({problem}); check the name and the PC's DNS or \
     /etc/hosts, or give an IP address", self.source_text()
)]
pub struct ResolveError {
    /// The key or flag that gave the address, e.g. `master.listen`.
    pub key: String,
    /// The address as written.
    pub addr: String,
    /// Its host.
    pub host: String,
    /// What the resolver said.
    pub problem: String,
}

impl ResolveError {
    /// Where the address came from, as written: `--master pc-0:4433` for a
    /// flag, `master.listen = "pc-0:4433"` for a config key.
    pub fn source_text(&self) -> String {
        if self.key.starts_with("--") {
            format!("{} {}", self.key, self.addr)
        } else {
            format!("{} = \"{}\"", self.key, self.addr)
        }
    }
}

/// The socket address of `addr`: an IP as given, a host name by the
/// system's resolver. Of a name's addresses the first IPv4 one is taken,
/// else the first: `localhost` is then 127.0.0.1 for the master and the
/// nodes alike, whatever order the resolver gives (the cluster's sockets
/// are IPv4 unless configured otherwise). `key` names where the address
/// came from in the error.
pub fn resolve(addr: &HostPort, key: &str) -> Result<SocketAddr, ResolveError> {
    if let Some(ip) = addr.ip() {
        return Ok(SocketAddr::new(ip, addr.port));
    }
    let err = |problem: String| ResolveError {
        key: key.to_owned(),
        addr: addr.to_string(),
        host: addr.host.clone(),
        problem,
    };
    let all: Vec<SocketAddr> = (addr.host.as_str(), addr.port)
        .to_socket_addrs()
        .map_err(|e| err(e.to_string()))?
        .collect();
    all.iter()
        .find(|a| a.is_ipv4())
        .or(all.first())
        .copied()
        .ok_or_else(|| err("it has no address".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ips_pass_and_names_resolve_ipv4_first() {
        let hp = |s: &str| s.parse::<HostPort>().unwrap();
        assert_eq!(
            resolve(&hp("10.0.0.1:4433"), "k").unwrap(),
            "10.0.0.1:4433".parse().unwrap()
        );
        assert_eq!(
            resolve(&hp("[::1]:7"), "k").unwrap(),
            "[::1]:7".parse().unwrap()
        );
        assert_eq!(
            resolve(&hp("localhost:4433"), "k").unwrap(),
            "127.0.0.1:4433".parse().unwrap()
        );
        // `.invalid` never resolves (RFC 6761).
        let err = resolve(&hp("no-such-pc.invalid:4433"), "master.listen").unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with(
                "master.listen = \"no-such-pc.invalid:4433\": cannot resolve host \"no-such-pc.invalid\""
            ),
            "{msg}"
        );
        assert!(msg.contains("or give an IP address"), "{msg}");
    }
}
