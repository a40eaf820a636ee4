//! Cluster transport shared by the master and the nodes: QUIC (quinn) with
//! mutual TLS against the cluster CA, and message framing over a stream.

pub mod stream;
pub mod tls;

pub use stream::{MessageReader, MessageStream, MessageWriter, StreamError};
pub use tls::{
    ALPN, ClusterIdentity, MASTER_SERVER_NAME, TlsError, client_config, peer_is, server_config,
};
