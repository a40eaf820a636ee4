//! Cluster transport shared by the master and the nodes: QUIC (quinn) with
//! mutual TLS against the cluster CA, and message framing over a stream.

pub mod addr;
pub mod stream;
pub mod tls;

pub use addr::{ResolveError, resolve};

pub use stream::{MessageReader, MessageStream, MessageWriter, REFUSED, StreamError};
pub use tls::{
    ALPN, CertProblem, ClusterIdentity, IDLE_TIMEOUT, KEEP_ALIVE, MASTER_SERVER_NAME, TlsError,
    client_config, peer_is, peer_names, server_config, server_endpoint_config,
};
