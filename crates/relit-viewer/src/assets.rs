//! The viewer's files, embedded in the binary: plain HTML, CSS, ES modules and GLSL
//! that the browser runs as they are (no bundler, no network).

/// `(path relative to the site root, MIME type, contents)`.
pub const ASSETS: &[(&str, &str, &str)] = &[
    (
        "index.html",
        "text/html; charset=utf-8",
        include_str!("../assets/index.html"),
    ),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("../assets/style.css"),
    ),
    (
        "main.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/main.js"),
    ),
    (
        "renderer.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/renderer.js"),
    ),
    (
        "vec.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/vec.js"),
    ),
    (
        "table.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/table.js"),
    ),
    (
        "environment.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/environment.js"),
    ),
    (
        "lights.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/lights.js"),
    ),
    (
        "panel.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/panel.js"),
    ),
    (
        "relight.frag",
        "text/plain; charset=utf-8",
        include_str!("../assets/relight.frag"),
    ),
    (
        "quad.vert",
        "text/plain; charset=utf-8",
        include_str!("../assets/quad.vert"),
    ),
];

/// The embedded asset at `path` (relative, no leading slash): MIME type and bytes.
pub fn asset(path: &str) -> Option<(&'static str, &'static [u8])> {
    ASSETS
        .iter()
        .find(|(p, _, _)| *p == path)
        .map(|(_, mime, body)| (*mime, body.as_bytes()))
}

/// The MIME type of a data file by its extension.
pub fn data_mime(path: &str) -> &'static str {
    match path.rsplit('.').next() {
        Some("json") => "application/json",
        Some("png") => "image/png",
        _ => "application/octet-stream",
    }
}
