//! The WebSocket side: one current-thread tokio runtime on its own thread accepts clients and
//! moves each client's queued messages to its socket. Nothing here touches shared memory.

use bridge::hub::{Hub, Outgoing};
use bridge::protocol::{self, SUBPROTOCOL};
use futures_util::{SinkExt, StreamExt};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio_tungstenite::tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tokio_tungstenite::tungstenite::http::{header, HeaderValue, StatusCode};
use tokio_tungstenite::tungstenite::Message;

/// Starts serving on `listener` (already bound, so a bad address fails at start-up).
pub fn spawn(listener: std::net::TcpListener, hub: Arc<Hub>) -> anyhow::Result<()> {
    listener.set_nonblocking(true)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()?;
    std::thread::Builder::new()
        .name("websocket".into())
        .spawn(move || runtime.block_on(serve(listener, hub)))?;
    Ok(())
}

async fn serve(listener: std::net::TcpListener, hub: Arc<Hub>) {
    let listener = match tokio::net::TcpListener::from_std(listener) {
        Ok(l) => l,
        Err(e) => {
            tracing::error!("websocket server cannot start: {e}");
            return;
        }
    };
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                tokio::spawn(client(stream, peer, hub.clone()));
            }
            Err(e) => {
                // Out of file descriptors and the like: wait instead of spinning.
                tracing::warn!("accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// Accepts the handshake only for clients that speak the Foxglove protocol, and selects it.
#[allow(clippy::result_large_err)]
fn negotiate(request: &Request, mut response: Response) -> Result<Response, ErrorResponse> {
    let offered = request
        .headers()
        .get_all(header::SEC_WEBSOCKET_PROTOCOL)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|p| p.trim() == SUBPROTOCOL);
    if !offered {
        let mut refusal = ErrorResponse::new(Some(format!("subprotocol {SUBPROTOCOL} required")));
        *refusal.status_mut() = StatusCode::BAD_REQUEST;
        return Err(refusal);
    }
    response.headers_mut().insert(
        header::SEC_WEBSOCKET_PROTOCOL,
        HeaderValue::from_static(SUBPROTOCOL),
    );
    Ok(response)
}

async fn client(stream: tokio::net::TcpStream, peer: SocketAddr, hub: Arc<Hub>) {
    let _ = stream.set_nodelay(true);
    let ws = match tokio_tungstenite::accept_hdr_async(stream, negotiate).await {
        Ok(ws) => ws,
        Err(e) => {
            tracing::info!(%peer, "websocket handshake failed: {e}");
            return;
        }
    };
    let (mut tx, mut rx) = ws.split();
    let (id, queue) = hub.connect();
    tracing::info!(%peer, clients = hub.client_count(), "client connected");
    let writer = async {
        while let Some(m) = queue.next().await {
            let message = match m {
                Outgoing::Text(t) => Message::Text(t.into()),
                Outgoing::Binary(b) => Message::Binary(b),
            };
            if tx.send(message).await.is_err() {
                break;
            }
        }
        let _ = tx.close().await;
    };
    let reader = async {
        while let Some(message) = rx.next().await {
            match message {
                Ok(Message::Text(text)) => match protocol::parse_request(&text) {
                    Ok(request) => hub.request(id, request),
                    Err(e) => hub.status(id, protocol::ERROR, &e.to_string()),
                },
                Ok(Message::Binary(_)) => {
                    hub.status(id, protocol::ERROR, "client publishing is not supported")
                }
                Ok(Message::Close(_)) | Err(_) => break,
                Ok(_) => {}
            }
        }
    };
    tokio::select! {
        _ = writer => {}
        _ = reader => {}
    }
    hub.disconnect(id);
    tracing::info!(%peer, "client disconnected");
}
