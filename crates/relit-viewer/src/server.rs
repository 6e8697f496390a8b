//! A small HTTP/1.1 server for the viewer (std::net, one thread per connection).
//!
//! It answers `GET` and `HEAD` for exactly two kinds of paths: the embedded assets
//! ([`crate::assets`]) and the files of one in-memory [`WebBundle`]. Nothing is ever
//! read from the file system, so no URL can reach outside what is served; paths with
//! `..` or `.` segments, backslashes, NUL or bad percent-escapes are refused with 400
//! before any lookup, unknown paths get 404, other methods 405.
//!
//! Every connection runs on its own thread, so a slow or idle client never holds up
//! another. What one client can take is bounded: the request head must arrive whole
//! within [`ServerOptions::head_timeout`] (however slowly its bytes trickle in) and be
//! at most [`MAX_HEAD`] bytes (431 past that, read no further); the response is written
//! in chunks that must each be taken within [`ServerOptions::write_timeout`]; at most
//! [`ServerOptions::max_connections`] are served at once (503 beyond). One request per
//! connection (`Connection: close`).

use crate::assets;
use crate::bundle::WebBundle;
use crate::{invalid, Result};
use std::borrow::Cow;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Connections served at once by default; more are answered 503 at once.
pub const MAX_CONNECTIONS: usize = 64;
/// The largest request head accepted (request line and headers).
pub const MAX_HEAD: usize = 16 * 1024;
/// Bytes of a response written per step of the write deadline.
const WRITE_CHUNK: usize = 64 * 1024;

/// Limits of a server (the defaults are what `relit view` uses).
#[derive(Clone, Copy, Debug)]
pub struct ServerOptions {
    /// Connections served at once; more are answered 503.
    pub max_connections: usize,
    /// Time from accepting a connection to the end of its request head; an idle or
    /// trickling client is dropped after it (408 if it sent anything).
    pub head_timeout: Duration,
    /// Time the client may take to accept each 64 KiB of the response.
    pub write_timeout: Duration,
}

impl Default for ServerOptions {
    fn default() -> Self {
        ServerOptions {
            max_connections: MAX_CONNECTIONS,
            head_timeout: Duration::from_secs(10),
            write_timeout: Duration::from_secs(30),
        }
    }
}

/// A server running on its own threads.
pub struct RunningServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    active: Arc<AtomicUsize>,
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

    /// Connections being served now (each on its own thread).
    pub fn active_connections(&self) -> usize {
        self.active.load(Ordering::SeqCst)
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

/// Serve the viewer and `bundle` on `host:port` (port 0: an ephemeral port) with the
/// default [`ServerOptions`].
pub fn serve(bundle: WebBundle, host: &str, port: u16) -> Result<RunningServer> {
    serve_with(bundle, host, port, ServerOptions::default())
}

/// Serve the viewer and `bundle` on `host:port` with `options`.
pub fn serve_with(
    bundle: WebBundle,
    host: &str,
    port: u16,
    options: ServerOptions,
) -> Result<RunningServer> {
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
    let (stop2, active2) = (stop.clone(), active.clone());
    let thread = std::thread::Builder::new()
        .name("relit-view-accept".into())
        .spawn(move || accept_loop(listener, bundle, stop2, active2, options))
        .map_err(|e| invalid(format!("cannot start the server thread: {e}")))?;
    Ok(RunningServer {
        addr,
        stop,
        active,
        thread: Some(thread),
    })
}

fn accept_loop(
    listener: TcpListener,
    bundle: Arc<WebBundle>,
    stop: Arc<AtomicBool>,
    active: Arc<AtomicUsize>,
    options: ServerOptions,
) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let mut stream = match stream {
            Ok(s) => s,
            Err(_) => {
                // Out of descriptors or a connection reset before accept: do not spin.
                std::thread::sleep(Duration::from_millis(20));
                continue;
            }
        };
        if active.fetch_add(1, Ordering::SeqCst) >= options.max_connections {
            active.fetch_sub(1, Ordering::SeqCst);
            // Tiny and written to a fresh socket's buffer; the short timeout is a guard
            // for the accept loop.
            let quick = ServerOptions {
                write_timeout: Duration::from_secs(1),
                ..options
            };
            let _ = write_response(&mut stream, 503, "text/plain", b"busy\n", false, &quick);
            continue;
        }
        let bundle = bundle.clone();
        let counter = Arc::new(ConnectionGuard(active.clone()));
        let spawned = std::thread::Builder::new()
            .name("relit-view-conn".into())
            .spawn(move || {
                let _guard = counter;
                handle(stream, &bundle, &options);
            });
        // When the thread cannot start, the closure is dropped unrun and its guard
        // gives the connection's slot back.
        drop(spawned);
    }
}

/// Gives a connection slot back when dropped (also when a handler panics).
struct ConnectionGuard(Arc<AtomicUsize>);

impl Drop for ConnectionGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A response: status, MIME type, body.
pub struct Response<'a> {
    pub status: u16,
    pub mime: &'static str,
    /// Borrowed from the assets or the bundle; a tile's, read for the request, owned.
    pub body: Cow<'a, [u8]>,
}

fn text(status: u16, body: &'static str) -> Response<'static> {
    Response {
        status,
        mime: "text/plain; charset=utf-8",
        body: Cow::Borrowed(body.as_bytes()),
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
            body: Cow::Borrowed(body),
        };
    }
    if let Some(body) = bundle.files.get(&path) {
        return Response {
            status: 200,
            mime: assets::data_mime(&path),
            body: Cow::Borrowed(body),
        };
    }
    if let Some((source, (level, x, y))) = bundle
        .tiles
        .as_deref()
        .and_then(|s| Some((s, s.parse_path(&path)?)))
    {
        if method == "HEAD" {
            // The tile's length without reading it (only the length is sent).
            return Response {
                status: 200,
                mime: "application/octet-stream",
                body: Cow::Owned(vec![0; source.tile_bytes(level, x, y)]),
            };
        }
        return match source.tile(level, x, y) {
            Ok(body) => Response {
                status: 200,
                mime: "application/octet-stream",
                body: Cow::Owned(body),
            },
            Err(e) => {
                eprintln!("relit view: tile {path}: {e}");
                text(500, "the tile could not be read\n")
            }
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

/// What reading a request head gave.
enum Head {
    Complete(Vec<u8>),
    /// Longer than [`MAX_HEAD`].
    TooLarge,
    /// The head did not arrive within the deadline (`true`: some of it did).
    TimedOut(bool),
    /// The client closed the connection or it failed.
    Closed,
}

/// Read up to the blank line that ends a request head, never more than
/// [`MAX_HEAD`] + one read, within `timeout` in all.
fn read_head(stream: &mut TcpStream, timeout: Duration) -> Head {
    let deadline = Instant::now() + timeout;
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 2048];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Head::TimedOut(!head.is_empty());
        }
        let _ = stream.set_read_timeout(Some(left));
        let n = match stream.read(&mut buf) {
            Ok(0) => return Head::Closed,
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return Head::TimedOut(!head.is_empty())
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => return Head::Closed,
        };
        // Only the new bytes (and the two before them) can complete the blank line.
        let from = head.len().saturating_sub(2);
        head.extend_from_slice(&buf[..n]);
        if let Some(end) = head_end(&head, from) {
            if end > MAX_HEAD {
                return Head::TooLarge;
            }
            head.truncate(end);
            return Head::Complete(head);
        }
        if head.len() > MAX_HEAD {
            return Head::TooLarge;
        }
    }
}

/// The end of the blank line that closes a request head (`\r\n\r\n`, or bare `\n`
/// line ends as RFC 9112 allows a server to accept), searching from `from`.
fn head_end(head: &[u8], from: usize) -> Option<usize> {
    (from..head.len()).find_map(|i| match head[i..] {
        [b'\n', b'\n', ..] => Some(i + 2),
        [b'\n', b'\r', b'\n', ..] => Some(i + 3),
        _ => None,
    })
}

fn handle(mut stream: TcpStream, bundle: &WebBundle, options: &ServerOptions) {
    let _ = stream.set_nodelay(true);
    let head = match read_head(&mut stream, options.head_timeout) {
        Head::Complete(h) => h,
        Head::TooLarge => {
            let _ = write_response(
                &mut stream,
                431,
                "text/plain",
                b"request head too large\n",
                false,
                options,
            );
            return;
        }
        Head::TimedOut(true) => {
            let _ = write_response(
                &mut stream,
                408,
                "text/plain",
                b"request timeout\n",
                false,
                options,
            );
            return;
        }
        Head::TimedOut(false) | Head::Closed => return,
    };
    let line = head.split(|&b| b == b'\n').next().unwrap_or(b"");
    let line = String::from_utf8_lossy(line);
    let mut parts = line.trim_end().split(' ');
    let (Some(method), Some(target), Some(version)) = (parts.next(), parts.next(), parts.next())
    else {
        let _ = write_response(
            &mut stream,
            400,
            "text/plain",
            b"bad request\n",
            false,
            options,
        );
        return;
    };
    if !version.starts_with("HTTP/1.") || parts.next().is_some() {
        let _ = write_response(
            &mut stream,
            400,
            "text/plain",
            b"bad request\n",
            false,
            options,
        );
        return;
    }
    let response = respond(bundle, method, target);
    let _ = write_response(
        &mut stream,
        response.status,
        response.mime,
        &response.body,
        method == "HEAD",
        options,
    );
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// Write all of `bytes`, each [`WRITE_CHUNK`] within `timeout`.
fn write_chunked(stream: &mut TcpStream, bytes: &[u8], timeout: Duration) -> std::io::Result<()> {
    for chunk in bytes.chunks(WRITE_CHUNK) {
        let deadline = Instant::now() + timeout;
        let mut rest = chunk;
        while !rest.is_empty() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(std::io::ErrorKind::TimedOut.into());
            }
            stream.set_write_timeout(Some(left))?;
            match stream.write(rest) {
                Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

fn write_response(
    stream: &mut TcpStream,
    status: u16,
    mime: &str,
    body: &[u8],
    head_only: bool,
    options: &ServerOptions,
) -> std::io::Result<()> {
    let head = format!(
        "HTTP/1.1 {status} {}\r\nContent-Type: {mime}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n\r\n",
        reason(status),
        body.len()
    );
    write_chunked(stream, head.as_bytes(), options.write_timeout)?;
    if !head_only {
        write_chunked(stream, body, options.write_timeout)?;
    }
    stream.flush()?;
    let _ = stream.shutdown(std::net::Shutdown::Write);
    if status >= 400 {
        drain(stream);
    }
    Ok(())
}

/// After an error answer, read (and drop) a little of what the client still sends, so
/// that closing with unread input does not reset the connection before the client has
/// read the answer. Bounded in bytes and time.
fn drain(stream: &mut TcpStream) {
    let deadline = Instant::now() + Duration::from_millis(500);
    let mut buf = [0u8; 4096];
    let mut total = 0usize;
    while total < 256 * 1024 {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            return;
        }
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => total += n,
        }
    }
}
