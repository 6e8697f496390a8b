//! The viewer's HTTP server: path traversal, unknown routes, concurrent clients.

mod common;

use relit_viewer::server::clean_path;
use relit_viewer::{serve, BundleOptions, PlaneStorage, WebBundle};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

fn bundle() -> WebBundle {
    let image = common::sample_image(48, 12, 3);
    WebBundle::build(
        &image,
        &BundleOptions {
            storage: PlaneStorage::U8,
            environments: vec![],
            source_name: "test.exr".into(),
        },
    )
    .unwrap()
}

/// Send a raw request, return (status, body).
fn request(addr: SocketAddr, raw: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    s.write_all(raw.as_bytes()).unwrap();
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).unwrap();
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
    if !raw.starts_with("HEAD") {
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
        "etc/passwd",
    ] {
        let (status, _) = get(addr, bad);
        assert!(status == 400 || status == 404, "{bad}: {status}");
    }
    assert_eq!(get(addr, "/../Cargo.toml").0, 400);
    assert_eq!(get(addr, "/%2e%2e/etc/passwd").0, 400);
    for unknown in [
        "/nope",
        "/data/",
        "/data/planes/L99.png",
        "/Cargo.toml",
        "/src/lib.rs",
        "/etc/passwd",
        "/data/info.json/x",
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

#[test]
fn twenty_concurrent_clients_get_correct_bodies() {
    let b = bundle();
    let expected: Vec<(String, Vec<u8>)> = b
        .files
        .iter()
        .map(|(k, v)| (format!("/{k}"), v.clone()))
        .chain(
            relit_viewer::assets::ASSETS
                .iter()
                .map(|(p, _, body)| (format!("/{p}"), body.as_bytes().to_vec())),
        )
        .collect();
    let server = serve(b, "127.0.0.1", 0).unwrap();
    let addr = server.addr();
    let barrier = std::sync::Arc::new(std::sync::Barrier::new(20));
    let threads: Vec<_> = (0..20)
        .map(|i| {
            let expected = expected.clone();
            let barrier = barrier.clone();
            std::thread::spawn(move || {
                barrier.wait();
                for j in 0..expected.len() {
                    let (path, body) = &expected[(i + j) % expected.len()];
                    let (status, got) = get(addr, path);
                    assert_eq!(status, 200, "{path}");
                    assert!(got == *body, "client {i}: wrong body for {path}");
                }
            })
        })
        .collect();
    for t in threads {
        t.join().expect("client thread");
    }
    server.stop();
}
