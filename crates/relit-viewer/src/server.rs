//! A small HTTP/1.1 server for the viewer (std::net, one thread per connection).
//!
//! It answers `GET` and `HEAD` for exactly two kinds of paths: the embedded assets
//! ([`crate::assets`]) and the files of one in-memory [`WebBundle`]. Nothing is ever
//! read from the file system, so no URL can reach outside what is served; paths with
//! `..` or `.` segments, backslashes, NUL or bad percent-escapes are refused with 400
//! before any lookup, unknown paths get 404, other methods 405.

use crate::assets;
use crate::bundle::WebBundle;
use crate::{invalid, Result};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Connections served at once; more are answered 503 at once.
pub const MAX_CONNECTIONS: usize = 64;
/// The largest request head accepted.
const MAX_HEAD: usize = 16 * 1024;

/// A server running on its own threads.
pub struct RunningServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl RunningServer {
    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The viewer's URL.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Block until the server stops (it never does unless [`Self::stop`] is called
    /// from elsewhere, so this is "serve forever").
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    /// Stop accepting connections and wait for the accept loop to end.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loop.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_millis(200));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for RunningServer {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shutdown();
        }
    }
}

/// Serve the viewer and `bundle` on `host:port` (port 0: an ephemeral port).
pub fn serve(bundle: WebBundle, host: &str, port: u16) -> Result<RunningServer> {
    let addrs: Vec<SocketAddr> = (host, port)
        .to_socket_addrs()
        .map_err(|e| invalid(format!("cannot resolve host `{host}`: {e}")))?
        .collect();
    let listener = TcpListener::bind(&addrs[..])
        .map_err(|e| invalid(format!("cannot listen on {host}:{port}: {e}")))?;
    let addr = listener
        .local_addr()
        .map_err(|e| invalid(format!("cannot read the listening address: {e}")))?;
    let stop = Arc::new(AtomicBool::new(false));
    let bundle = Arc::new(bundle);
    let active = Arc::new(AtomicUsize::new(0));
    let stop2 = stop.clone();
    let thread = std::thread::Builder::new()
        .name("relit-view-accept".into())
        .spawn(move || {
            for stream in listener.incoming() {
                if stop2.load(Ordering::SeqCst) {
                    break;
                }
                let Ok(mut stream) = stream else { continue };
                if active.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
                    active.fetch_sub(1, Ordering::SeqCst);
                    let _ = write_response(&mut stream, 503, "text/plain", b"busy\n", false);
                    continue;
                }
                let bundle = bundle.clone();
                let active = active.clone();
                let spawned = std::thread::Builder::new()
                    .name("relit-view-conn".into())
                    .spawn(move || {
                        handle(stream, &bundle);
                        active.fetch_sub(1, Ordering::SeqCst);
                    });
                if spawned.is_err() {
                    // The closure (and its counter decrement) was dropped unrun.
                }
            }
        })
        .map_err(|e| invalid(format!("cannot start the server thread: {e}")))?;
    Ok(RunningServer {
        addr,
        stop,
        thread: Some(thread),
    })
}

/// A response: status, MIME type, body.
pub struct Response<'a> {
    pub status: u16,
    pub mime: &'static str,
    pub body: &'a [u8],
}

fn text(status: u16, body: &'static str) -> Response<'static> {
    Response {
        status,
        mime: "text/plain; charset=utf-8",
        body: body.as_bytes(),
    }
}

/// What the server answers to `method target` (pure: no I/O).
pub fn respond<'a>(bundle: &'a WebBundle, method: &str, target: &str) -> Response<'a> {
    if method != "GET" && method != "HEAD" {
        return text(405, "method not allowed\n");
    }
    let path = match clean_path(target) {
        Ok(p) => p,
        Err(status) => return text(status, "bad request path\n"),
    };
    let path = if path.is_empty() {
        "index.html".to_string()
    } else {
        path
    };
    if let Some((mime, body)) = assets::asset(&path) {
        return Response {
            status: 200,
            mime,
            body,
        };
    }
    if let Some(body) = bundle.files.get(&path) {
        return Response {
            status: 200,
            mime: assets::data_mime(&path),
            body,
        };
    }
    text(404, "not found\n")
}

/// The request path without its leading slash, query or fragment, percent-decoded;
/// `Err(400)` for anything that could name a parent or another root.
pub fn clean_path(target: &str) -> std::result::Result<String, u16> {
    let raw = target.split(['?', '#']).next().unwrap_or("");
    let raw = raw.strip_prefix('/').ok_or(400u16)?;
    let bytes = raw.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).ok_or(400u16)?;
            let s = std::str::from_utf8(hex).map_err(|_| 400u16)?;
            out.push(u8::from_str_radix(s, 16).map_err(|_| 400u16)?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let path = String::from_utf8(out).map_err(|_| 400u16)?;
    if path.contains(['\\', '\0', ':']) || path.starts_with('/') {
        return Err(400);
    }
    if path.split('/').any(|seg| seg == ".." || seg == ".") {
        return Err(400);
    }
    Ok(path)
}

fn handle(mut stream: TcpStream, bundle: &WebBundle) {
    let _ = stream.set_read_timeout(Some(Duration::from_secs(15)));
    let _ = stream.set_write_timeout(Some(Duration::from_secs(60)));
    let _ = stream.set_nodelay(true);
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 2048];
    loop {
        if head.windows(4).any(|w| w == b"\r\n\r\n") {
            break;
        }
        if head.len() > MAX_HEAD {
            let _ = write_response(
                &mut stream,
                431,
                "text/plain",
                b"request too large\n",
                false,
            );
            return;
        }
        match stream.read(&mut buf) {
            Ok(0) => return,
            Ok(n) => head.extend_from_slice(&buf[..n]),
            Err(_) => return,
        }
    }
    let line = head.split(|&b| b == b'\n').next().unwrap_or(b"");
    let line = String::from_utf8_lossy(line);
    let mut parts = line.trim_end().split(' ');
    let (Some(method), Some(target), Some(version)) = (parts.next(), parts.next(), parts.next())
    else {
        let _ = write_response(&mut stream, 400, "text/plain", b"bad request\n", false);
        return;
    };
    if !version.starts_with("HTTP/1.") || parts.next().is_some() {
        let _ = write_response(&mut stream, 400, "text/plain", b"bad request\n", false);
        return;
    }
    let response = respond(bundle, method, target);
    let _ = write_response(
        &mut stream,
        response.status,
        response.mime,
        response.body,
        method == "HEAD",
    );
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

fn write_response(
    stream: &mut TcpStream,
    status: u16,
    mime: &str,
    body: &[u8],
    head_only: bool,
) -> std::io::Result<()> {
    let head = format!(
        "HTTP/1.1 {status} {}\r\nContent-Type: {mime}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n\r\n",
        reason(status),
        body.len()
    );
    stream.write_all(head.as_bytes())?;
    if !head_only {
        stream.write_all(body)?;
    }
    stream.flush()?;
    let _ = stream.shutdown(std::net::Shutdown::Write);
    Ok(())
}
