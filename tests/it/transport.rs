//! Real QUIC on loopback with mutual TLS: a node with a certificate from
//! the cluster CA is accepted; one without a certificate, one signed by
//! another CA, and one claiming another node's name are refused.

use showcase_master::certs::{self, ClusterCerts, MASTER_FILE, MASTER_SERVER_NAME};
use showcase_proto::{Capabilities, Hello, Message, PROTOCOL_VERSION, Role, Welcome};
use showcase_render::net::{ClusterIdentity, MessageStream, client_config, peer_is, server_config};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::timeout;

const LIMIT: Duration = Duration::from_secs(10);

fn identity(c: &ClusterCerts, name: &str) -> ClusterIdentity {
    let p = c.peers.iter().find(|p| p.name == name).unwrap();
    ClusterIdentity::from_pem(&c.ca_pem, &p.cert_pem, &p.key_pem).unwrap()
}

fn hello(node: &str) -> Message {
    Message::Hello(Hello {
        protocol_version: PROTOCOL_VERSION,
        node: node.into(),
        role: Role::Projector,
        capabilities: Capabilities::default(),
    })
}

/// A master that accepts connections, reads one Hello per connection and
/// answers Welcome only when the certificate matches the claimed name.
/// Reports each connection's outcome.
async fn master(
    c: &ClusterCerts,
) -> (
    quinn::Endpoint,
    SocketAddr,
    tokio::sync::mpsc::Receiver<Result<String, String>>,
) {
    let cfg = server_config(&identity(c, MASTER_FILE)).unwrap();
    let ep = quinn::Endpoint::server(cfg, "127.0.0.1:0".parse().unwrap()).unwrap();
    let addr = ep.local_addr().unwrap();
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    let server = ep.clone();
    tokio::spawn(async move {
        while let Some(incoming) = server.accept().await {
            let tx = tx.clone();
            tokio::spawn(async move {
                let outcome = async {
                    let conn = incoming.await.map_err(|e| format!("handshake: {e}"))?;
                    let (send, recv) = conn.accept_bi().await.map_err(|e| e.to_string())?;
                    let mut s = MessageStream::new(send, recv);
                    let Message::Hello(h) = s.recv().await.map_err(|e| e.to_string())? else {
                        return Err("first message was not Hello".to_string());
                    };
                    if !peer_is(&conn, &h.node) {
                        conn.close(1u32.into(), b"certificate does not match node name");
                        return Err(format!("{} presented another node's certificate", h.node));
                    }
                    s.send(&Message::Welcome(Welcome {
                        protocol_version: PROTOCOL_VERSION,
                        target_hz: 60.0,
                        deadline_ms: 50.0,
                    }))
                    .await
                    .map_err(|e| e.to_string())?;
                    // Keep the connection open until the node is done.
                    let _ = s.recv().await;
                    Ok(h.node)
                }
                .await;
                let _ = tx.send(outcome).await;
            });
        }
    });
    (ep, addr, rx)
}

/// Connect as a node and wait for Welcome.
async fn join(cfg: quinn::ClientConfig, addr: SocketAddr, name: &str) -> Result<(), String> {
    let mut ep = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
    ep.set_default_client_config(cfg);
    let conn = ep
        .connect(addr, MASTER_SERVER_NAME)
        .map_err(|e| e.to_string())?
        .await
        .map_err(|e| format!("handshake: {e}"))?;
    let (send, recv) = conn.open_bi().await.map_err(|e| e.to_string())?;
    let mut s = MessageStream::new(send, recv);
    s.send(&hello(name)).await.map_err(|e| e.to_string())?;
    match s.recv().await.map_err(|e| e.to_string())? {
        Message::Welcome(_) => {
            conn.close(0u32.into(), b"done");
            Ok(())
        }
        other => Err(format!("unexpected {}", other.kind())),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mutual_tls_admits_only_cluster_certificates() {
    let cluster = certs::generate(&["node-a".into(), "node-b".into()]).unwrap();
    let rogue = certs::generate(&["node-a".into()]).unwrap();
    let (_ep, addr, mut outcomes) = master(&cluster).await;

    // A genuine node joins.
    let good = client_config(&identity(&cluster, "node-a")).unwrap();
    timeout(LIMIT, join(good, addr, "node-a"))
        .await
        .unwrap()
        .expect("a node with a cluster certificate is admitted");
    assert_eq!(
        timeout(LIMIT, outcomes.recv()).await.unwrap(),
        Some(Ok("node-a".into()))
    );

    // A node whose certificate is signed by another CA (it trusts our CA,
    // so it can verify the master, but the master must not trust it).
    let mut foreign = identity(&rogue, "node-a");
    foreign.ca = identity(&cluster, "node-a").ca;
    let err = timeout(
        LIMIT,
        join(client_config(&foreign).unwrap(), addr, "node-a"),
    )
    .await
    .unwrap()
    .expect_err("a certificate from another CA is refused");
    let seen = timeout(LIMIT, outcomes.recv()).await.unwrap().unwrap();
    assert!(
        seen.is_err(),
        "master accepted a foreign certificate: {seen:?} / {err}"
    );
    eprintln!("foreign certificate: node saw {err:?}, master saw {seen:?}");

    // A node with no client certificate at all.
    let roots = {
        let mut r = rustls::RootCertStore::empty();
        r.add(identity(&cluster, "node-a").ca).unwrap();
        Arc::new(r)
    };
    let mut tls = rustls::ClientConfig::builder_with_provider(Arc::new(
        rustls::crypto::ring::default_provider(),
    ))
    .with_protocol_versions(&[&rustls::version::TLS13])
    .unwrap()
    .with_root_certificates(roots)
    .with_no_client_auth();
    tls.alpn_protocols = vec![showcase_render::net::ALPN.to_vec()];
    let anon = quinn::ClientConfig::new(Arc::new(
        quinn::crypto::rustls::QuicClientConfig::try_from(tls).unwrap(),
    ));
    timeout(LIMIT, join(anon, addr, "node-a"))
        .await
        .unwrap()
        .expect_err("a node without a certificate is refused");
    let seen = timeout(LIMIT, outcomes.recv()).await.unwrap().unwrap();
    assert!(
        seen.is_err(),
        "master accepted a node without certificate: {seen:?}"
    );

    // A genuine node that claims to be another node.
    let b = client_config(&identity(&cluster, "node-b")).unwrap();
    timeout(LIMIT, join(b, addr, "node-a"))
        .await
        .unwrap()
        .expect_err("node-b may not join as node-a");
    let seen = timeout(LIMIT, outcomes.recv()).await.unwrap().unwrap();
    assert_eq!(
        seen,
        Err("node-a presented another node's certificate".into())
    );
}
