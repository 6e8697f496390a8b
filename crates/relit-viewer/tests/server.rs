//! The viewer's HTTP server: path traversal, unknown routes, concurrent clients.

mod common;

use relit::storage::Precision;
use relit_viewer::server::{clean_path, MAX_HEAD};
use relit_viewer::{serve, serve_with, BundleOptions, ServerOptions, WebBundle};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

fn bundle() -> WebBundle {
    let image = common::sample_image(48, 12, 3);
    WebBundle::build(
        &image,
        &BundleOptions {
            precision: Precision::U8,
            environments: vec![],
            source_name: "test.exr".into(),
            ..Default::default()
        },
    )
    .unwrap()
}

/// Read a whole response (until the server closes), return (status, body).
fn read_response(s: &mut TcpStream, head_request: bool) -> (u16, Vec<u8>) {
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut buf = Vec::new();
    let mut chunk = [0u8; 8192];
    loop {
        match s.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            // A reset after the answer (the client still had unsent bytes) ends it too.
            Err(e) if !buf.is_empty() && e.kind() == std::io::ErrorKind::ConnectionReset => break,
            Err(e) => panic!("reading the response: {e}"),
        }
    }
    parse_response(&buf, head_request)
}

/// Send a raw request, return (status, body).
fn request(addr: SocketAddr, raw: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.write_all(raw.as_bytes()).unwrap();
    read_response(&mut s, raw.starts_with("HEAD"))
}

fn parse_response(buf: &[u8], head_request: bool) -> (u16, Vec<u8>) {
    let split = buf
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("response head");
    let head = String::from_utf8_lossy(&buf[..split]).to_string();
    let status: u16 = head.split(' ').nth(1).unwrap().parse().unwrap();
    let length: usize = head
        .lines()
        .find_map(|l| l.strip_prefix("Content-Length: "))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    let body = buf[split + 4..].to_vec();
    if !head_request {
        assert_eq!(body.len(), length, "Content-Length matches the body");
    }
    (status, body)
}

fn get(addr: SocketAddr, path: &str) -> (u16, Vec<u8>) {
    request(addr, &format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n"))
}

#[test]
fn serves_assets_and_data() {
    let b = bundle();
    let info = b.info().to_vec();
    let server = serve(b, "127.0.0.1", 0).unwrap();
    let addr = server.addr();
    assert!(addr.ip().is_loopback());
    let (status, body) = get(addr, "/");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&body).contains("<canvas"));
    assert_eq!(get(addr, "/main.js").0, 200);
    assert_eq!(get(addr, "/relight.frag").0, 200);
    assert_eq!(get(addr, "/data/info.json"), (200, info));
    assert_eq!(get(addr, "/data/info.json?x=1").0, 200);
    assert_eq!(get(addr, "/data/planes/L00.png").0, 200);
    assert_eq!(get(addr, "/data/depth.f32").1.len(), 48 * 12 * 4);
    let (status, body) = request(addr, "HEAD /data/info.json HTTP/1.1\r\n\r\n");
    assert_eq!((status, body.len()), (200, 0));
    // Bare LF line ends are accepted too.
    assert_eq!(request(addr, "GET /main.js HTTP/1.1\nHost: x\n\n").0, 200);
    assert_eq!(request(addr, "GET /main.js HTTP/1.0\n\n").0, 200);
    server.stop();
}

#[test]
fn refuses_traversal_and_unknown_routes() {
    let server = serve(bundle(), "127.0.0.1", 0).unwrap();
    let addr = server.addr();
    for bad in [
        "/../Cargo.toml",
        "/data/../../etc/passwd",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/data/%2E%2E/info.json",
        "/..%2fCargo.toml",
        "/data\\..\\info.json",
        "/./index.html",
        "/%00",
        "/%zz",
        "//etc/passwd",
        "/C:/Windows/win.ini",
        "/C:%5CWindows%5Cwin.ini",
        "etc/passwd",
        "/%5c..%5cCargo.toml",
        "/data%5c..%5c..%5cCargo.toml",
        "/%2F%2Fetc/passwd",
        "/%2fetc/passwd",
        "/data/%2e%2e%2f%2e%2e%2fCargo.toml",
        "/data/.%2e/info.json",
        "/data/%2e/info.json",
        "/data/planes/..",
        "/data/planes/.",
        "http://127.0.0.1/../Cargo.toml",
        "*",
    ] {
        let (status, _) = get(addr, bad);
        assert!(status == 400 || status == 404, "{bad}: {status}");
    }
    assert_eq!(get(addr, "/../Cargo.toml").0, 400);
    assert_eq!(get(addr, "/%2e%2e/etc/passwd").0, 400);
    assert_eq!(get(addr, "/data%5c..%5cinfo.json").0, 400);
    assert_eq!(get(addr, "/%2F%2Fetc/passwd").0, 400);
    // No double decoding: `%252e%252e` is the literal name `%2e%2e`, which is not served.
    assert_eq!(get(addr, "/data/%252e%252e/%252e%252e/Cargo.toml").0, 404);
    for unknown in [
        "/nope",
        "/data/",
        "/data/planes/L99.png",
        "/Cargo.toml",
        "/src/lib.rs",
        "/etc/passwd",
        "/data/info.json/x",
        "/data/depth.f32x",
        "/DATA/INFO.JSON",
        "/index.html/",
        "/....//Cargo.toml",
        "/tests/server.rs",
        "/assets/main.js",
        "/proc/self/environ",
    ] {
        assert_eq!(get(addr, unknown).0, 404, "{unknown}");
    }
    assert_eq!(
        request(addr, "POST / HTTP/1.1\r\nContent-Length: 0\r\n\r\n").0,
        405
    );
    assert_eq!(request(addr, "garbage\r\n\r\n").0, 400);
    server.stop();
}

#[test]
fn clean_path_rules() {
    assert_eq!(clean_path("/").unwrap(), "");
    assert_eq!(
        clean_path("/data/info.json?v=2#x").unwrap(),
        "data/info.json"
    );
    assert_eq!(clean_path("/a%20b").unwrap(), "a b");
    for bad in [
        "", "x", "/..", "/a/../b", "/a/./b", "/%2e%2e", "/a%5c..", "/%", "/%2", "/%c3%28",
    ] {
        assert_eq!(clean_path(bad), Err(400), "{bad}");
    }
}

/// Every file the server should answer with, by URL path.
fn expected_files(b: &WebBundle) -> Vec<(String, Vec<u8>)> {
    b.files
        .iter()
        .map(|(k, v)| (format!("/{k}"), v.clone()))
        .chain(
            relit_viewer::assets::ASSETS
                .iter()
                .map(|(p, _, body)| (format!("/{p}"), body.as_bytes().to_vec())),
        )
        .collect()
}

/// Wait until `f` holds (polling), or panic after `timeout` with `what`.
fn wait_for(what: &str, timeout: Duration, mut f: impl FnMut() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn twenty_concurrent_clients_are_served_at_once() {
    let b = bundle();
    let expected = Arc::new(expected_files(&b));
    let server = Arc::new(serve(b, "127.0.0.1", 0).unwrap());
    let addr = server.addr();
    // Every client opens its connection and sends half a request head; only when all 20
    // connections are open at the server at the same time do they finish, in reverse
    // order of arrival. A server that handled connections one after another would sit
    // on the first one while the other 19 waited.
    let opened = Arc::new(Barrier::new(21));
    let go = Arc::new(Barrier::new(21));
    let threads: Vec<_> = (0..20)
        .map(|i| {
            let (expected, opened, go) = (expected.clone(), opened.clone(), go.clone());
            std::thread::spawn(move || {
                let (path, body) = &expected[i % expected.len()];
                let mut s = TcpStream::connect(addr).unwrap();
                s.write_all(format!("GET {path} HTTP/1.1\r\nHost: x\r\n").as_bytes())
                    .unwrap();
                opened.wait();
                go.wait();
                std::thread::sleep(Duration::from_millis(5 * (20 - i as u64)));
                s.write_all(b"\r\n").unwrap();
                let (status, got) = read_response(&mut s, false);
                assert_eq!(status, 200, "{path}");
                assert!(got == *body, "client {i}: wrong body for {path}");
                // Then more requests each, overlapping the other clients' ones.
                for j in 1..expected.len() {
                    let (path, body) = &expected[(i + j) % expected.len()];
                    let (status, got) = get(addr, path);
                    assert_eq!(status, 200, "{path}");
                    assert!(got == *body, "client {i}: wrong body for {path}");
                }
            })
        })
        .collect();
    opened.wait();
    wait_for("20 connections at once", Duration::from_secs(10), || {
        server.active_connections() == 20
    });
    go.wait();
    for t in threads {
        t.join().expect("client thread");
    }
    wait_for("all connections closed", Duration::from_secs(10), || {
        server.active_connections() == 0
    });
}

fn quick_options() -> ServerOptions {
    ServerOptions {
        head_timeout: Duration::from_millis(1500),
        ..ServerOptions::default()
    }
}

#[test]
fn idle_and_trickling_clients_neither_block_others_nor_stay() {
    let server = serve_with(bundle(), "127.0.0.1", 0, quick_options()).unwrap();
    let addr = server.addr();
    // 30 clients that connect and say nothing, 5 that stop halfway through the head.
    let mut idle: Vec<TcpStream> = (0..30).map(|_| TcpStream::connect(addr).unwrap()).collect();
    for _ in 0..5 {
        let mut s = TcpStream::connect(addr).unwrap();
        s.write_all(b"GET /index.html HTTP/1.1\r\nHost").unwrap();
        idle.push(s);
    }
    wait_for("35 idle connections", Duration::from_secs(5), || {
        server.active_connections() == 35
    });
    // Meanwhile others are served at once.
    let start = Instant::now();
    for _ in 0..5 {
        assert_eq!(get(addr, "/data/info.json").0, 200);
    }
    assert!(
        start.elapsed() < Duration::from_millis(1200),
        "served while 35 idle"
    );
    // A client trickling one byte every 100 ms is cut off at the head deadline (408),
    // not kept as long as it keeps sending.
    let mut slow = TcpStream::connect(addr).unwrap();
    let t0 = Instant::now();
    let request =
        b"GET /index.html HTTP/1.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
    for byte in request {
        if slow.write_all(&[*byte]).is_err() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
        if t0.elapsed() > Duration::from_secs(3) {
            break;
        }
    }
    let (status, _) = read_response(&mut slow, false);
    assert_eq!(status, 408);
    assert!(t0.elapsed() < Duration::from_secs(4), "{:?}", t0.elapsed());
    // The idle ones were dropped by the server: those that sent part of a head got 408,
    // the silent ones an end of stream.
    for (i, s) in idle.iter_mut().enumerate() {
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut buf = Vec::new();
        let _ = s.read_to_end(&mut buf);
        if i < 30 {
            assert!(buf.is_empty(), "idle client {i} got {buf:?}");
        } else {
            assert!(buf.starts_with(b"HTTP/1.1 408"), "half-sent client {i}");
        }
    }
    wait_for("idle connections closed", Duration::from_secs(5), || {
        server.active_connections() == 0
    });
}

#[test]
fn connections_past_the_limit_get_503_then_service_resumes() {
    let options = ServerOptions {
        max_connections: 4,
        ..quick_options()
    };
    let server = serve_with(bundle(), "127.0.0.1", 0, options).unwrap();
    let addr = server.addr();
    let idle: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(addr).unwrap()).collect();
    wait_for("4 idle connections", Duration::from_secs(5), || {
        server.active_connections() == 4
    });
    assert_eq!(get(addr, "/").0, 503);
    drop(idle);
    wait_for("slots given back", Duration::from_secs(5), || {
        server.active_connections() == 0
    });
    assert_eq!(get(addr, "/").0, 200);
}

#[test]
fn huge_request_heads_are_refused_without_reading_them() {
    let server = serve(bundle(), "127.0.0.1", 0).unwrap();
    let addr = server.addr();
    // Many headers, together under the limit: fine.
    let mut ok = String::from("GET /data/info.json HTTP/1.1\r\n");
    while ok.len() < MAX_HEAD - 200 {
        ok.push_str(&format!("X-Pad-{}: {}\r\n", ok.len(), "p".repeat(60)));
    }
    ok.push_str("\r\n");
    assert_eq!(request(addr, &ok).0, 200);
    // Just over the limit: 431.
    let mut over = String::from("GET / HTTP/1.1\r\nX-Big: ");
    over.push_str(&"b".repeat(MAX_HEAD));
    over.push_str("\r\n\r\n");
    assert_eq!(request(addr, &over).0, 431);
    // 64 MiB of one header line: 431 long before the client could send it all, and the
    // server hangs up instead of reading (and keeping) the rest.
    let mut s = TcpStream::connect(addr).unwrap();
    let mut writer = s.try_clone().unwrap();
    let sender = std::thread::spawn(move || {
        let _ = writer.set_write_timeout(Some(Duration::from_secs(20)));
        let _ = writer.write_all(b"GET / HTTP/1.1\r\nX-Huge: ");
        let line = vec![b'h'; 1 << 20];
        let mut sent = 0usize;
        for _ in 0..64 {
            match writer.write_all(&line) {
                Ok(()) => sent += line.len(),
                Err(_) => break,
            }
        }
        sent
    });
    let (status, _) = read_response(&mut s, false);
    assert_eq!(status, 431);
    let sent = sender.join().unwrap();
    assert!(sent < 64 << 20, "the server took all {sent} bytes");
    wait_for("connection closed", Duration::from_secs(5), || {
        server.active_connections() == 0
    });
}
