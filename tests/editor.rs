//! `assetfield edit` end to end (issue 19): a small scene is synthesised, trained briefly and
//! mined with ground-truth names; the editor serves it, and
//! - the HTTP API is driven endpoint by endpoint: the token, a bad edit (400 with its
//!   line:column, nothing changed), an oversized body, undo / redo, renders, the bird's-eye
//!   view, and a save that `assetfield layout` resolves and that composes (through the
//!   library, not the session) to the image the server rendered;
//! - the page is driven in headless Chromium over WebDriver: one instance is dragged on the
//!   bird's-eye view, the layout moves it by the dragged distance, the 3D view changes where
//!   the object stood, undo restores the image exactly, Shift+Q turns it to the next 15
//!   degrees, a library asset clicked into the plane lands where it was clicked, and a
//!   screenshot is saved.

use assetfield_editor::{EditSession, SessionOptions, ViewRequest};
use assetfield_layout::resolve;
use assetfield_scene::{AssetLibrary, Composer, ScriptAssets};
use assetfield_tests::{SCENE, assetfield_bin, column_opacity, ok, scratch};
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The mined library of the tiny scene, built once per test process.
fn library() -> &'static Path {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let dir = scratch("editor");
        std::fs::write(dir.join("tiny.ron"), SCENE).unwrap();
        let synth = [
            "synth",
            "tiny.ron",
            "--out",
            "d",
            "--views",
            "20",
            "--test-views",
            "1",
            "--res",
            "48",
            "--aa",
            "1",
        ];
        ok(&dir, &synth);
        let train = [
            "train",
            "d",
            "--out",
            "f.safetensors",
            "--iters",
            "900",
            "--res",
            "80",
            "--batch",
            "2048",
        ];
        ok(&dir, &train);
        ok(
            &dir,
            &["mine", "f.safetensors", "--out", "lib", "--gt", "d/gt_layout.json", "--gt-names"],
        );
        dir.join("lib")
    })
}

/// A running `assetfield edit`, stopped when dropped.
struct Server {
    child: Child,
    host: String,
    token: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_server(lib: &Path, extra: &[&str]) -> Server {
    let mut child = Command::new(assetfield_bin())
        .arg("edit")
        .arg(lib)
        .args(["--port", "0", "--backend", "cpu"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("assetfield edit starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url = line
        .trim()
        .strip_prefix("listening on http://")
        .unwrap_or_else(|| panic!("the first line on stdout must be the URL, got {line:?}"));
    let (host, token) = url.split_once("/?token=").expect("URL with a token");
    assert!(host.starts_with("127.0.0.1:"), "bound to 127.0.0.1 by default: {host}");
    assert_eq!(token.len(), 32, "a 128-bit token: {token}");
    Server { child, host: host.to_string(), token: token.to_string() }
}

/// A response: status, headers (lower-case names) and body.
struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Reply {
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&self.body)))
    }
    fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
    }
}

/// One HTTP/1.1 request (the server and chromedriver both speak it; no client crate needed).
fn http(host: &str, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Reply {
    let mut s = TcpStream::connect(host).unwrap_or_else(|e| panic!("connect {host}: {e}"));
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    s.write_all(req.as_bytes()).unwrap();
    // a server may answer (400) before reading a long body and close: ignore write errors
    let _ = s.write_all(body);
    // read the head, then exactly the body it announces (a server may keep the connection)
    let mut raw = Vec::new();
    let mut buf = [0u8; 65536];
    let split = loop {
        if let Some(p) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
            break p;
        }
        match s.read(&mut buf) {
            Ok(0) | Err(_) => {
                panic!("{method} {path}: the connection closed before the reply's head")
            }
            Ok(n) => raw.extend_from_slice(&buf[..n]),
        }
    };
    let head_lc = String::from_utf8_lossy(&raw[..split]).to_ascii_lowercase();
    let length = head_lc
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|v| v.trim().parse::<usize>().ok());
    let chunked = head_lc.contains("transfer-encoding: chunked");
    loop {
        let have = raw.len() - split - 4;
        let done = match length {
            Some(n) => have >= n,
            None if chunked => raw.ends_with(b"0\r\n\r\n"),
            None => false,
        };
        if done {
            break;
        }
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => raw.extend_from_slice(&buf[..n]),
        }
    }
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let mut lines = head.lines();
    let status = lines.next().and_then(|l| l.split(' ').nth(1)).and_then(|c| c.parse().ok());
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let mut body = raw[split + 4..].to_vec();
    if headers.iter().any(|(k, v)| k == "transfer-encoding" && v.contains("chunked")) {
        body = dechunk(&body);
    }
    Reply { status: status.expect("a status code"), headers, body }
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let Some(eol) = b.windows(2).position(|w| w == b"\r\n") else { return out };
        let size =
            usize::from_str_radix(String::from_utf8_lossy(&b[..eol]).trim(), 16).unwrap_or(0);
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + size]);
        b = &b[eol + 2 + size + 2..];
    }
}

impl Server {
    fn get(&self, path: &str) -> Reply {
        http(&self.host, "GET", path, &[("X-Assetfield-Token", &self.token)], b"")
    }
    fn post(&self, path: &str, body: &str) -> Reply {
        http(&self.host, "POST", path, &[("X-Assetfield-Token", &self.token)], body.as_bytes())
    }
    fn url(&self) -> String {
        format!("http://{}/?token={}", self.host, self.token)
    }
}

fn decode_png(bytes: &[u8]) -> image::RgbImage {
    image::load_from_memory(bytes).expect("a PNG").to_rgb8()
}

fn instance<'a>(layout: &'a Value, key: &str) -> &'a Value {
    layout["instances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|i| i["key"] == key)
        .unwrap_or_else(|| panic!("no instance {key} in {layout}"))
}

fn xy(i: &Value) -> (f64, f64) {
    (i["x"].as_f64().unwrap(), i["y"].as_f64().unwrap())
}

#[test]
fn the_api_answers_every_endpoint_and_guards_the_session() {
    let lib = library();
    let _ = std::fs::remove_file(lib.join("edited.ron"));
    let s = start_server(lib, &[]);

    // the token guards the API (not the page)
    assert_eq!(http(&s.host, "GET", "/api/layout", &[], b"").status, 403);
    let wrong = [("X-Assetfield-Token", "0123")];
    assert_eq!(http(&s.host, "POST", "/api/edits", &wrong, b"[Remove(\"w0\")]").status, 403);
    assert_eq!(http(&s.host, "POST", "/api/save", &[], b"").status, 403);
    let page = http(&s.host, "GET", "/", &[], b"");
    assert_eq!(page.status, 200);
    assert!(String::from_utf8_lossy(&page.body).contains("editor.js"));
    assert_eq!(http(&s.host, "GET", "/editor.js", &[], b"").status, 200);
    // a page whose domain was rebound to 127.0.0.1 sends its own Host: refused, page too
    let port = s.host.rsplit(':').next().unwrap();
    let rebound = format!("evil.example:{port}");
    let mut raw = TcpStream::connect(&s.host).unwrap();
    write!(raw, "GET / HTTP/1.1\r\nHost: {rebound}\r\nConnection: close\r\n\r\n").unwrap();
    let mut reply = String::new();
    let _ = raw.read_to_string(&mut reply);
    assert!(reply.starts_with("HTTP/1.1 403"), "{reply}");
    let by_query = http(&s.host, "GET", &format!("/api/layout?token={}", s.token), &[], b"");
    assert_eq!(by_query.status, 200);

    let layout = s.get("/api/layout").json();
    assert_eq!(layout["version"], 0);
    for key in ["w0", "w1", "w2", "b0", "b1"] {
        let i = instance(&layout, key);
        assert!(i["category"].is_string() && i["asset"].is_string() && i["scale"] == 1.0, "{i}");
    }
    assert!(!layout["categories"].as_array().unwrap().is_empty());
    assert!(!layout["assets"].as_array().unwrap().is_empty());
    let (x0, y0) = xy(instance(&layout, "w0"));

    // renders and the bird's-eye view
    let r = s.get("/api/render?width=96&height=64&azimuth=30&elevation=40");
    assert_eq!(r.status, 200);
    assert_eq!(r.header("content-type"), Some("image/png"));
    let before = decode_png(&r.body);
    assert_eq!(before.dimensions(), (96, 64));
    for bad in ["width=0", "width=99999", "elevation=120", "azimuth=nan", "width=abc", "radius=-1"]
    {
        let r = s.get(&format!("/api/render?{bad}"));
        assert_eq!(r.status, 400, "{bad}: {}", String::from_utf8_lossy(&r.body));
    }
    let bev = s.get("/api/bev");
    assert_eq!(bev.status, 200);
    let m = &layout["bev"];
    assert_eq!(
        decode_png(&bev.body).dimensions(),
        (m["width"].as_u64().unwrap() as u32, m["height"].as_u64().unwrap() as u32)
    );
    assert_eq!(s.get("/api/bev?footprints=false").status, 200);

    // a good edit moves w0; bad ones answer 400 with their place and change nothing
    let moved = s.post("/api/edits", "[Move(target: \"w0\", by: (0.5, -0.25))]");
    assert_eq!(moved.status, 200, "{}", String::from_utf8_lossy(&moved.body));
    let moved = moved.json();
    assert_eq!(moved["version"], 1);
    let (x1, y1) = xy(instance(&moved, "w0"));
    assert!((x1 - x0 - 0.5).abs() < 1e-4 && (y1 - y0 + 0.25).abs() < 1e-4, "{x1} {y1}");
    assert!(moved["edits"].as_str().unwrap().contains("Move("), "{}", moved["edits"]);
    assert_eq!(moved["can_undo"], true);
    let after = decode_png(&s.get("/api/render?width=96&height=64&azimuth=30&elevation=40").body);
    assert_ne!(before, after, "the render follows the edit");
    for (body, line, col) in [
        (
            "[\n  Move(target: \"w0\", by: (1, 0)),\n  Move(target: \"nobody\", by: (1, 0)),\n]",
            3,
            3,
        ),
        ("[Move(target: \"w0\", by: (1, 0)", 1, 30),
        ("[Rotate(target: \"w0\", by: (1, 0))]", 1, 1),
    ] {
        let r = s.post("/api/edits", body);
        assert_eq!(r.status, 400, "{body}");
        let e = r.json();
        assert!(e["error"].as_str().unwrap().contains("edit request"), "{e}");
        assert_eq!(e["line"].as_u64(), Some(line), "{body}: {e}");
        if body.contains("nobody") {
            assert_eq!(e["col"].as_u64(), Some(col), "{e}");
        }
    }
    let huge = vec![b' '; assetfield_editor::MAX_BODY_BYTES + 10];
    let r = http(&s.host, "POST", "/api/edits", &[("X-Assetfield-Token", &s.token)], &huge);
    assert_eq!(r.status, 400);
    let r = http(&s.host, "POST", "/api/edits", &[("X-Assetfield-Token", &s.token)], &[0xff, 0xfe]);
    assert_eq!(r.status, 400);
    let r = s.post("/api/edits", "[Move(target: \"w0\", by: (1e39, 0))]");
    assert_eq!(r.status, 400, "a position beyond f32: {}", String::from_utf8_lossy(&r.body));
    let r = s.post("/api/edits", "[Move(target: \"w0\", by: (900.0, 0))]");
    assert_eq!(r.status, 400, "off the plane: {}", String::from_utf8_lossy(&r.body));
    let still = s.get("/api/layout").json();
    assert_eq!(still["version"], 1, "refused edits change nothing");
    assert_eq!(xy(instance(&still, "w0")), (x1, y1));
    assert_eq!(s.get("/api/layout?nonsense=1").status, 200);
    assert_eq!(s.get("/api/nothing").status, 404);

    // undo restores the render exactly, redo brings the edit back
    let undone = s.post("/api/undo", "").json();
    assert_eq!(xy(instance(&undone, "w0")), (x0, y0));
    assert_eq!(undone["can_redo"], true);
    let again = decode_png(&s.get("/api/render?width=96&height=64&azimuth=30&elevation=40").body);
    assert_eq!(before, again, "undo restores the image exactly");
    assert_eq!(s.post("/api/undo", "").json()["version"], undone["version"], "nothing to undo");
    let redone = s.post("/api/redo", "").json();
    assert_eq!(xy(instance(&redone, "w0")), (x1, y1));
    // undo after a removal (the instance comes back as a new entity) is exact too
    let before_remove = s.get("/api/render?width=96&height=64&azimuth=30&elevation=40").body;
    assert_eq!(s.post("/api/edits", "[Remove(\"b1\")]").status, 200);
    assert_ne!(s.get("/api/render?width=96&height=64&azimuth=30&elevation=40").body, before_remove);
    s.post("/api/undo", "");
    let back = s.get("/api/render?width=96&height=64&azimuth=30&elevation=40").body;
    assert!(back == before_remove, "undoing a removal restores the image exactly");
    let added = s.post("/api/edits", "[Add(asset: \"obj000\", at: (0.0, 0.0), yaw: 45, name: \"new\"), Duplicate(target: \"b0\", by: (0.0, 0.8))]");
    assert_eq!(added.status, 200, "{}", String::from_utf8_lossy(&added.body));
    instance(&added.json(), "new");

    // recolour a category from an entry of another category
    let cats = added.json()["categories"].as_array().unwrap().clone();
    let (cat, from) = (cats[0]["name"].as_str().unwrap(), cats[1]["members"][0].as_str().unwrap());
    let r = s.post(&format!("/api/recolour?category={cat}&from={from}"), "");
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    let recoloured = r.json();
    let name = format!("{cat}~{from}");
    let of_cat: Vec<&Value> = recoloured["instances"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|i| i["category"] == cat)
        .collect();
    assert!(!of_cat.is_empty() && of_cat.iter().all(|i| i["asset"] == name.as_str()), "{of_cat:?}");
    // drawn with the template now, each keeps the orientation its own entry was cut with
    let index = AssetLibrary::open(lib).unwrap().index;
    let cut_yaw =
        |asset: &str| index.entries.iter().find(|e| e.name == asset).map_or(0.0, |e| e.yaw_deg);
    for i in &of_cat {
        let was = instance(&added.json(), i["key"].as_str().unwrap()).clone();
        let want =
            was["yaw_deg"].as_f64().unwrap() + cut_yaw(was["asset"].as_str().unwrap()) as f64;
        let off = (i["yaw_deg"].as_f64().unwrap() - want).rem_euclid(360.0);
        assert!(
            off.min(360.0 - off) < 1e-3,
            "{}: yaw {} after recolouring, {want} wanted",
            i["key"],
            i["yaw_deg"]
        );
    }
    // each category has a thumbnail (its template from above) and can be given a name
    let thumb = s.get(&format!("/api/thumbnail?category={cat}"));
    assert_eq!(thumb.status, 200, "{}", String::from_utf8_lossy(&thumb.body));
    let t = decode_png(&thumb.body);
    assert!(t.width() >= 32 && t.height() >= 16, "{:?}", t.dimensions());
    let (lo, hi) = t.pixels().fold((255u8, 0u8), |(lo, hi), p| (lo.min(p.0[1]), hi.max(p.0[1])));
    assert!(hi > lo + 60, "the template shows on its thumbnail ({lo}..{hi})");
    assert_eq!(s.get("/api/thumbnail?category=nope").status, 400);
    let named =
        s.post("/api/edits", &format!("[NameCategory(category: \"{cat}\", name: \"chairs\")]"));
    assert_eq!(named.status, 200, "{}", String::from_utf8_lossy(&named.body));
    let named = named.json();
    let c =
        named["categories"].as_array().unwrap().iter().find(|c| c["name"] == cat).unwrap().clone();
    assert_eq!(c["label"], "chairs");
    let r = s.post("/api/edits", &format!("[NameCategory(category: \"{cat}\", name: \" \")]"));
    assert_eq!(r.status, 400, "an empty name");
    assert_eq!(s.post("/api/recolour?category=nope&from=obj000", "").status, 400);
    assert_eq!(s.post(&format!("/api/recolour?category={cat}&from=nope"), "").status, 400);
    assert_eq!(s.post("/api/recolour", "").status, 400, "missing query");

    // save writes base + edits; the file resolves and composes to the server's image
    let saved = s.post("/api/save", "");
    assert_eq!(saved.status, 200);
    let path = PathBuf::from(saved.json()["saved"].as_str().unwrap());
    assert_eq!(path, lib.join("edited.ron"));
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("base: \"layout.ron\"") && text.contains("Add("), "{text}");
    assert!(text.contains("color_from") && text.contains("path: \".\""), "{text}");
    assert!(text.contains("NameCategory(") && text.contains("\"chairs\""), "{text}");
    ok(lib, &["layout", "edited.ron"]);
    let view = ViewRequest {
        width: 80,
        height: 60,
        azimuth_deg: -40.0,
        elevation_deg: 30.0,
        radius: None,
    };
    let served = decode_png(&s.get("/api/render?width=80&height=60&azimuth=-40&elevation=30").body);
    let library = AssetLibrary::open(lib).unwrap();
    let script = assetfield_layout::load(&path).unwrap();
    let assets = ScriptAssets::resolve(&script, &library, None).unwrap();
    let resolved = resolve(&script, &assets).unwrap();
    let mut composer = Composer::new(library.composition(&library.default_canvas()).unwrap());
    assets.install(&mut composer).unwrap();
    composer.apply_layout(&resolved).unwrap();
    composer.update();
    let session = EditSession::open(lib, &SessionOptions::default(), None).unwrap();
    let camera = session.camera(&view).unwrap();
    let rgb = composer.render(&camera, library.background);
    let composed = decode_png(&assetfield_editor::png::encode_rgb_f32(80, 60, rgb).unwrap());
    assert_eq!(served, composed, "the saved layout composes to the image the server rendered");
    // a new session continues the saved edits: its own, listed as a script writes them
    // (no `Some(...)`), and undone one by one
    assert_eq!(session.layout().objects().count(), resolved.objects().count());
    assert!(session.layout().instances.iter().any(|i| i.key == "new"));
    let mut session = session;
    let log = session.edits_ron();
    assert!(log.contains("Add(") && log.contains("ReplaceAsset("), "{log}");
    assert!(!log.contains("Some("), "the log writes what a person types: {log}");
    let n = session.edits().len();
    assert!(session.view().can_undo, "the reopened session's edits can be undone");
    assert!(session.undo().unwrap());
    assert_eq!(session.edits().len(), n - 1);
    assert!(session.view().can_redo);
    let text = session.saved_text().unwrap();
    assert_eq!(text.matches("Add(").count(), 1, "edits are saved once: {text}");
    // the server survives all of that
    assert_eq!(s.get("/api/layout").status, 200);
}

/// Resident memory of process `pid`, bytes (Linux).
fn rss_bytes(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kb * 1024)
}

#[test]
fn a_session_stays_bounded_and_reading_it_never_waits() {
    let lib = library();
    let dir = scratch("editor-bounded");
    let saved = dir.join("bounded.ron");
    let s = start_server(lib, &["--layout", saved.to_str().unwrap(), "--render-budget", "2"]);

    // names are never patterns: a key names its instance as written
    for bad in [
        "[Add(asset: \"obj000\", at: (0.0, 0.0), name: \"obj*\")]",
        "[Duplicate(target: \"w0\", by: (0.0, 0.5), name: \"?\")]",
        "[Add(asset: \"obj000\", at: (0.0, 0.0), name: \"\")]",
    ] {
        let r = s.post("/api/edits", bad);
        assert_eq!(r.status, 400, "{bad}: {}", String::from_utf8_lossy(&r.body));
        assert!(r.json()["error"].as_str().unwrap().contains("name"), "{bad}");
    }

    // a batch that would make more instances than the session allows is refused whole,
    // naming the limit, and changes nothing
    let start = s.get("/api/layout").json();
    let count = start["instances"].as_array().unwrap().len();
    let doubling = vec!["Duplicate(target: \"*\", by: (0.0, 0.0))"; 16].join(", ");
    let r = s.post("/api/edits", &format!("[{doubling}]"));
    assert_eq!(r.status, 400, "{}", String::from_utf8_lossy(&r.body));
    let e = r.json()["error"].as_str().unwrap().to_string();
    assert!(e.contains("instances per script") && e.contains("20000"), "{e}");
    let after = s.get("/api/layout").json();
    assert_eq!(after["version"], start["version"]);
    assert_eq!(after["instances"].as_array().unwrap().len(), count);

    // a render over the session's budget is cancelled, and reading the layout meanwhile
    // does not wait for it
    let (host, token) = (s.host.clone(), s.token.clone());
    let big = std::thread::spawn(move || {
        let t = Instant::now();
        let r = http(
            &host,
            "GET",
            "/api/render?width=2048&height=2048",
            &[("X-Assetfield-Token", &token)],
            b"",
        );
        (r.status, String::from_utf8_lossy(&r.body).into_owned(), t.elapsed())
    });
    std::thread::sleep(Duration::from_millis(300));
    let t = Instant::now();
    assert_eq!(s.get("/api/layout").status, 200);
    let waited = t.elapsed();
    let (status, body, took) = big.join().unwrap();
    assert!(waited < Duration::from_secs(1), "GET /api/layout waited {waited:?} for a render");
    if took > Duration::from_millis(2500) {
        assert_eq!(status, 400, "a render past its budget is cancelled: {body}");
        assert!(body.contains("cancelled"), "{body}");
    }

    // a thousand one-line moves: memory grows with the edits, not their square
    let pid = s.child.id();
    let before = rss_bytes(pid);
    for k in 0..1000 {
        let by = if k % 2 == 0 { 0.01 } else { -0.01 };
        let r = s.post("/api/edits", &format!("[Move(target: \"w0\", by: ({by}, 0.0))]"));
        assert_eq!(r.status, 200, "move {k}: {}", String::from_utf8_lossy(&r.body));
    }
    if let (Some(a), Some(b)) = (before, rss_bytes(pid)) {
        let grown = b.saturating_sub(a) as f64 / 1e6;
        println!("RSS {:.0} MB -> {:.0} MB after 1000 moves", a as f64 / 1e6, b as f64 / 1e6);
        assert!(grown < 150.0, "1000 one-line moves grew the server by {grown:.0} MB");
    }
    // undo walks back through them
    let undone = s.post("/api/undo", "").json();
    assert_eq!(undone["can_undo"], true);

    // the bird's-eye view, redrawn only where edits changed it, is the picture a fresh
    // session draws of the same layout
    assert_eq!(
        s.post("/api/edits", "[Move(target: \"b0\", by: (0.3, 0.2)), Remove(\"w1\")]").status,
        200
    );
    let served = s.get("/api/bev?footprints=false");
    assert_eq!(served.status, 200);
    assert_eq!(s.post("/api/save", "").status, 200);
    let opts = SessionOptions { layout: Some(saved.clone()), ..Default::default() };
    let mut fresh = EditSession::open(lib, &opts, None).unwrap();
    assert_eq!(fresh.version(), 0);
    assert!(
        fresh.bev_png(false).unwrap() == served.body,
        "incremental and full bird's-eye views differ"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `assetfield edit LIB 2>&1 | head -1`: once the reader has its line, standard output and
/// error are closed pipes; Ctrl-C and SIGTERM still stop the server.
#[cfg(unix)]
#[test]
fn signals_stop_the_editor_whatever_became_of_its_output() {
    let lib = library();
    let dir = scratch("editor-signals");
    for signal in ["INT", "TERM"] {
        let mut child = Command::new(assetfield_bin())
            .arg("edit")
            .arg(lib)
            .args(["--port", "0", "--backend", "cpu", "--layout"])
            .arg(dir.join("signals.ron"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stderr.take());
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        assert!(line.starts_with("listening on"), "{line}");
        std::thread::sleep(Duration::from_millis(300));
        let kill =
            Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status();
        assert!(kill.unwrap().success());
        let start = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if start.elapsed() > Duration::from_secs(30) {
                let _ = child.kill();
                panic!("SIG{signal} did not stop the editor with its output pipes closed");
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        assert!(status.success(), "SIG{signal}: {status}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Where an instance was removed, the scene is what the layout without it composes to, and
/// the vacated ground looks like the container's empty floor around it.
#[test]
fn a_removed_instance_leaves_no_trace() {
    let lib = library();
    let dir = scratch("editor-residue");
    let opts = |name: &str| SessionOptions { layout: Some(dir.join(name)), ..Default::default() };
    let mut session = EditSession::open(lib, &opts("removed.ron"), None).unwrap();
    let view = ViewRequest {
        width: 96,
        height: 72,
        azimuth_deg: -50.0,
        elevation_deg: 40.0,
        radius: None,
    };
    let gone = session.layout().by_key("b1").expect("b1").clone();
    session.apply("[Remove(\"b1\")]").unwrap();
    let after = session.render(&view).unwrap();
    session.save().unwrap();
    let mut fresh = EditSession::open(lib, &opts("removed.ron"), None).unwrap();
    assert!(
        fresh.render(&view).unwrap() == after,
        "a removal renders as the layout composed without it"
    );

    // the vacated footprint against a ring of empty floor around it (summed column opacity)
    let comp = session.composer().composition();
    let [cols, rows, _] = comp.field.config.res;
    let opacity = column_opacity(&comp.field);
    let g = comp.grid;
    let b = gone.bev_aabb;
    let (mut inside, mut ring) = (vec![], vec![]);
    let margin = 3.0 * g.step.x.max(g.step.y);
    for r in 0..rows {
        for c in 0..cols {
            let p = g.min + glam::Vec2::new(c as f32 * g.step.x, r as f32 * g.step.y);
            let within = |m: f32| {
                p.x >= b.min.x - m && p.x <= b.max.x + m && p.y >= b.min.y - m && p.y <= b.max.y + m
            };
            let near_other = session.layout().objects().any(|i| {
                let o = i.bev_aabb;
                p.x >= o.min.x - margin
                    && p.x <= o.max.x + margin
                    && p.y >= o.min.y - margin
                    && p.y <= o.max.y + margin
            });
            if within(0.0) {
                inside.push(opacity[r * cols + c]);
            } else if within(2.0 * margin) && !within(margin) && !near_other {
                ring.push(opacity[r * cols + c]);
            }
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
    assert!(!inside.is_empty() && !ring.is_empty());
    let (a, f) = (mean(&inside), mean(&ring));
    println!("vacated footprint: summed column opacity {a:.3}; empty floor around it {f:.3}");
    assert!(
        (a - f).abs() < 0.1 * f.max(0.1),
        "the vacated footprint ({a:.3}) differs from the floor around it ({f:.3})"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- the page in headless Chromium --------------------------------------------------

/// WebDriver's key codes of the modifiers.
const SHIFT: &str = "\u{E008}";
const CONTROL: &str = "\u{E009}";

fn strict() -> bool {
    std::env::var_os("ASSETFIELD_STRICT_TESTS").is_some_and(|v| v != "0")
}

fn find_program(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    for dir in std::env::split_paths(&path).chain([PathBuf::from("/usr/lib/chromium")]) {
        for n in names {
            let p = dir.join(n);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

/// A chromedriver process and one headless Chromium session.
struct Browser {
    driver: Child,
    host: String,
    session: String,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = http(&self.host, "DELETE", &format!("/session/{}", self.session), &[], b"");
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

impl Browser {
    fn start(chromium: &Path, driver: &Path) -> Browser {
        // a free port, released and handed to chromedriver: another process may take it in
        // between, so a driver that exits at once is started again on another port
        let (driver, host) = (0..3)
            .find_map(|_| {
                let port = std::net::TcpListener::bind("127.0.0.1:0")
                    .unwrap()
                    .local_addr()
                    .unwrap()
                    .port();
                let mut child = Command::new(driver)
                    .arg(format!("--port={port}"))
                    .stdout(Stdio::null())
                    .stderr(Stdio::null())
                    .spawn()
                    .expect("chromedriver starts");
                let host = format!("127.0.0.1:{port}");
                let t0 = Instant::now();
                while TcpStream::connect(&host).is_err() {
                    if child.try_wait().ok().flatten().is_some() {
                        return None;
                    }
                    assert!(t0.elapsed() < Duration::from_secs(30), "chromedriver did not listen");
                    std::thread::sleep(Duration::from_millis(100));
                }
                Some((child, host))
            })
            .expect("chromedriver exited three times at start");
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": chromium.display().to_string(),
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                         "--window-size=1280,1000", "--force-device-scale-factor=1"],
            },
        }}});
        let mut b = Browser { driver, host, session: String::new() };
        let r = b.call("POST", "/session", Some(caps));
        b.session = r["sessionId"].as_str().expect("a WebDriver session").to_string();
        b
    }

    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let body = body.map(|v| v.to_string()).unwrap_or_default();
        let headers = [("Content-Type", "application/json")];
        let r = http(&self.host, method, path, &headers, body.as_bytes());
        let v: Value = serde_json::from_slice(&r.body).unwrap_or(Value::Null);
        assert_eq!(r.status, 200, "WebDriver {method} {path}: {v}");
        v["value"].clone()
    }

    fn cmd(&self, method: &str, what: &str, body: Option<Value>) -> Value {
        self.call(method, &format!("/session/{}/{what}", self.session), body)
    }

    fn script(&self, js: &str) -> Value {
        self.cmd("POST", "execute/sync", Some(json!({"script": js, "args": []})))
    }

    /// Press `key` while holding `modifier` (a WebDriver key code: [`SHIFT`], [`CONTROL`]).
    fn chord(&self, modifier: &str, key: &str) {
        let keys = json!([
            {"type": "keyDown", "value": modifier}, {"type": "keyDown", "value": key},
            {"type": "keyUp", "value": key}, {"type": "keyUp", "value": modifier}]);
        let actions = json!({"actions": [{"type": "key", "id": "keyboard", "actions": keys}]});
        self.cmd("POST", "actions", Some(actions));
    }

    fn wait_for(&self, js: &str, what: &str) {
        let t0 = Instant::now();
        let js = format!("return ({js});");
        while self.script(&js) != Value::Bool(true) {
            assert!(t0.elapsed() < Duration::from_secs(60), "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The 3D view's image as displayed (drawn onto a canvas in the page).
    fn view_image(&self) -> image::RgbImage {
        let url = self.script(
            "const i = document.getElementById('view'); const c = document.createElement('canvas');
             c.width = i.naturalWidth; c.height = i.naturalHeight;
             c.getContext('2d').drawImage(i, 0, 0); return c.toDataURL('image/png');",
        );
        let b64 = url.as_str().unwrap().split_once(',').unwrap().1;
        decode_png(&base64(b64))
    }
}

fn base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' => Some(62),
        b'/' => Some(63),
        _ => None,
    };
    let digits: Vec<u8> = s.bytes().filter_map(val).collect();
    let mut out = Vec::with_capacity(digits.len() * 3 / 4);
    for chunk in digits.chunks(4) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0u32, |acc, (k, &d)| acc | (u32::from(d) << (18 - 6 * k)));
        let bytes = n.to_be_bytes();
        out.extend_from_slice(&bytes[1..chunk.len()]);
    }
    out
}

#[test]
fn base64_decodes() {
    assert_eq!(base64("aGVsbG8gd29ybGQ="), b"hello world");
    assert_eq!(base64("YQ=="), b"a");
    assert_eq!(base64("YWI="), b"ab");
}

#[test]
fn the_page_drags_an_instance_and_undo_restores_the_view() {
    let (Some(chromium), Some(driver)) = (
        find_program(&["chromium", "chromium-browser", "google-chrome"]),
        find_program(&["chromedriver"]),
    ) else {
        let msg = "SKIPPED: the browser test needs chromium and chromedriver (Debian: apt install chromium chromium-driver; .ci/run installs them)";
        assert!(!strict(), "{msg} (ASSETFIELD_STRICT_TESTS is set)");
        eprintln!("{msg}");
        return;
    };
    let lib = library();
    let layout_file = lib.join("browser.ron");
    let _ = std::fs::remove_file(&layout_file);
    let s = start_server(lib, &["--layout", layout_file.to_str().unwrap()]);
    let b = Browser::start(&chromium, &driver);
    b.cmd("POST", "url", Some(json!({"url": s.url()})));
    let full_render = |v: u64| {
        format!(
            "window.editor && editor.ready && editor.shown.version === {v} && editor.shown.preview === false"
        )
    };
    b.wait_for(&full_render(0), "the page and its first full render");
    let state = b.script(
        "return [document.getElementById('unsaved').hidden, document.getElementById('edit-text').value];",
    );
    assert_eq!(state[0], true, "nothing is unsaved yet");
    assert!(
        state[1].as_str().unwrap().contains("Move(target: \""),
        "the example edit names an instance: {state}"
    );
    let before = b.view_image();
    let layout = s.get("/api/layout").json();
    let key = "b0";
    let (x0, y0) = xy(instance(&layout, key));

    // drag b0 by (60, -30) CSS pixels on the bird's-eye view
    let centre = b.script(&format!(
        "const r = document.querySelector('#bev-svg polygon[data-key=\"{key}\"]').getBoundingClientRect();
         return [r.left + r.width / 2, r.top + r.height / 2];"
    ));
    let (cx, cy) = (centre[0].as_f64().unwrap().round(), centre[1].as_f64().unwrap().round());
    let (dx, dy) = (60.0, -30.0);
    let pointer = |x: f64, y: f64, ms: u64| json!({"type": "pointerMove", "duration": ms, "x": x as i64, "y": y as i64, "origin": "viewport"});
    b.cmd(
        "POST",
        "actions",
        Some(json!({"actions": [{"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"},
            "actions": [pointer(cx, cy, 0), {"type": "pointerDown", "button": 0},
                        pointer(cx + dx / 2.0, cy + dy / 2.0, 100), pointer(cx + dx, cy + dy, 100),
                        {"type": "pointerUp", "button": 0}]}]})),
    );
    b.wait_for(&full_render(1), "the render after the drag");
    assert_eq!(
        b.script("return document.getElementById('unsaved').hidden;"),
        false,
        "unsaved marker"
    );
    let upc = b.script("return editor.unitsPerCssPixel();");
    let (ux, uy) = (upc[0].as_f64().unwrap(), upc[1].as_f64().unwrap());
    let moved = s.get("/api/layout").json();
    let (x1, y1) = xy(instance(&moved, key));
    let (want_x, want_y) = (dx * ux, -dy * uy);
    assert!(
        ((x1 - x0) - want_x).abs() <= 1.01 * ux && ((y1 - y0) - want_y).abs() <= 1.01 * uy,
        "dragged by ({want_x:.3}, {want_y:.3}) world units, the layout moved ({:.3}, {:.3})",
        x1 - x0,
        y1 - y0
    );
    let after = b.view_image();
    assert_eq!(before.dimensions(), after.dimensions());

    // the view changed, and around where the object stood
    let (w, h) = after.dimensions();
    // a session of its own (the API test writes LIB/edited.ron meanwhile), for the camera
    let own = SessionOptions { layout: Some(lib.join("camera_only.ron")), ..Default::default() };
    let session = EditSession::open(lib, &own, None).unwrap();
    let view = b.script("return [editor.view.azimuth, editor.view.elevation];");
    let camera = session
        .camera(&ViewRequest {
            width: w,
            height: h,
            azimuth_deg: view[0].as_f64().unwrap() as f32,
            elevation_deg: view[1].as_f64().unwrap() as f32,
            radius: None,
        })
        .unwrap();
    let at = camera.project(glam::Vec3::new(x0 as f32, y0 as f32, 0.15)).expect("b0 in view");
    let changed: Vec<(u32, u32)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let (p, q) = (before.get_pixel(x, y).0, after.get_pixel(x, y).0);
            (0..3).any(|c| p[c].abs_diff(q[c]) > 24)
        })
        .collect();
    assert!(!changed.is_empty(), "the 3D view did not change");
    assert!(changed.len() < (w * h / 3) as usize, "{} of {} pixels changed", changed.len(), w * h);
    let near = changed
        .iter()
        .filter(|&&(x, y)| (x as f32 - at.x).hypot(y as f32 - at.y) < 0.12 * w as f32)
        .count();
    assert!(near > 0, "no pixel changed near b0's old place {at} (changed: {})", changed.len());

    // undo (the button) restores the image exactly
    b.script("document.getElementById('undo').click(); return true;");
    b.wait_for(&full_render(2), "the render after undo");
    let undone = b.view_image();
    assert!(undone == before, "undo must restore the 3D view exactly");
    assert_eq!(xy(instance(&s.get("/api/layout").json(), key)), (x0, y0));

    // Shift+Q turns the selected instance (b0, selected by the drag) to the next 15 degrees
    let yaw0 = instance(&s.get("/api/layout").json(), key)["yaw_deg"].as_f64().unwrap();
    b.chord(SHIFT, "q");
    b.wait_for(&full_render(3), "the render after the turn");
    let yaw1 = instance(&s.get("/api/layout").json(), key)["yaw_deg"].as_f64().unwrap();
    let want = ((yaw0 / 15.0).round() + 1.0) * 15.0;
    let off = (yaw1 - want).rem_euclid(360.0);
    assert!(off.min(360.0 - off) < 1e-3, "Shift+Q: {yaw0} -> {yaw1}, wanted {want}");

    // Ctrl-D duplicates the selected instance (the page sends its key, never a pattern)
    let count = |l: &Value| l["instances"].as_array().unwrap().len();
    let n0 = count(&s.get("/api/layout").json());
    b.chord(CONTROL, "d");
    b.wait_for(&full_render(4), "the render after Ctrl-D");
    let duplicated = s.get("/api/layout").json();
    assert_eq!(count(&duplicated), n0 + 1, "Ctrl-D makes one copy");
    instance(&duplicated, &format!("{key}+copy1"));

    // choose a library asset, click on an empty spot of the plane: a new instance there
    let asset = b.script(
        "const li = document.querySelector('#palette li'); li.click(); return li.dataset.asset;",
    );
    let asset = asset.as_str().unwrap().to_string();
    let spot = b.script(
        "const r = document.getElementById('bev-svg').getBoundingClientRect();
         for (const fy of [0.12, 0.5, 0.88]) for (const fx of [0.12, 0.5, 0.88]) {
           const x = Math.round(r.left + fx * r.width), y = Math.round(r.top + fy * r.height);
           const hit = document.elementFromPoint(x, y);
           if (hit && hit.id === 'bev-svg') return [x, y];
         }
         return null;",
    );
    let (sx, sy) =
        (spot[0].as_f64().expect("an empty spot on the plane"), spot[1].as_f64().unwrap());
    b.cmd(
        "POST",
        "actions",
        Some(json!({"actions": [{"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"},
            "actions": [pointer(sx, sy, 0), {"type": "pointerDown", "button": 0}, {"type": "pointerUp", "button": 0}]}]})),
    );
    b.wait_for(&full_render(5), "the render after the insert");
    let inserted = s.get("/api/layout").json();
    let new = instance(&inserted, &format!("{asset}+new1"));
    let at = b.script(&format!(
        "const r = document.getElementById('bev-svg').getBoundingClientRect(); const m = editor.layout.bev;
         const u = ({sx} - r.left) * m.width / r.width, v = ({sy} - r.top) * m.height / r.height;
         return [m.x0 + u * m.sx, m.y0 - v * m.sy];"
    ));
    let (wx, wy) = (at[0].as_f64().unwrap(), at[1].as_f64().unwrap());
    let (nx, ny) = xy(new);
    assert!(
        (nx - wx).abs() <= 1.01 * ux && (ny - wy).abs() <= 1.01 * uy,
        "inserted at ({nx}, {ny}), clicked ({wx}, {wy})"
    );

    // the category panel: draw a category with its template; the dropdown keeps the choice,
    // each instance keeps its orientation (its entry's cut turn), and the colours are the
    // server's
    let chosen = b.script(
        "const li = document.querySelector('#categories li'); const sel = li.querySelector('select');
         sel.value = li.dataset.category; sel.dispatchEvent(new Event('change'));
         return li.dataset.category;",
    );
    let cat = chosen.as_str().unwrap().to_string();
    let was = s.get("/api/layout").json();
    b.wait_for(&full_render(6), "the render after ReplaceAsset");
    let now = s.get("/api/layout").json();
    let index = AssetLibrary::open(lib).unwrap().index;
    let cut =
        |a: &str| index.entries.iter().find(|e| e.name == a).map_or(0.0, |e| e.yaw_deg) as f64;
    for i in now["instances"].as_array().unwrap().iter().filter(|i| i["category"] == cat.as_str()) {
        assert_eq!(i["asset"], cat.as_str());
        let w = instance(&was, i["key"].as_str().unwrap());
        let want = w["yaw_deg"].as_f64().unwrap() + cut(w["asset"].as_str().unwrap());
        let off = (i["yaw_deg"].as_f64().unwrap() - want).rem_euclid(360.0);
        assert!(off.min(360.0 - off) < 1e-3, "{}: yaw {} wanted {want}", i["key"], i["yaw_deg"]);
    }
    let panel = b.script(&format!(
        "const li = document.querySelector('#categories li[data-category=\"{cat}\"]');
         return [li.querySelector('select').value, li.querySelector('.swatch').style.background,
                 editor.layout.category_colours['{cat}']];"
    ));
    assert_eq!(panel[0], cat.as_str(), "the dropdown shows the choice after the change");
    let hex = panel[2].as_str().unwrap();
    let rgb = (1..7)
        .step_by(2)
        .map(|k| u8::from_str_radix(&hex[k..k + 2], 16).unwrap())
        .collect::<Vec<_>>();
    assert_eq!(panel[1], format!("rgb({}, {}, {})", rgb[0], rgb[1], rgb[2]), "{panel}");
    // every category shows its thumbnail; Rename names it (the page asks with a prompt)
    b.wait_for(
        "[...document.querySelectorAll('#categories img.thumb')].every((i) => i.complete && i.naturalWidth > 0)",
        "the category thumbnails",
    );
    b.script(&format!(
        "window.prompt = () => 'tables'; [...document.querySelectorAll('#categories li[data-category=\"{cat}\"] button')].find((x) => x.textContent === 'Rename').click(); return true;"
    ));
    b.wait_for(
        &format!("document.querySelector('#categories li[data-category=\"{cat}\"] .label').textContent.startsWith('tables')"),
        "the renamed category",
    );
    b.wait_for(&full_render(7), "the layout after the rename");

    // the example edit applies as it stands
    b.script("document.getElementById('apply-text').click(); return true;");
    b.wait_for(&full_render(8), "the render after the example edit");
    assert_eq!(b.script("return document.getElementById('edit-error').textContent;"), "");

    // a screenshot under the test's output
    let shot = b.cmd("GET", "screenshot", None);
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("editor");
    std::fs::create_dir_all(&out).unwrap();
    let file = out.join("screenshot.png");
    std::fs::write(&file, base64(shot.as_str().unwrap())).unwrap();
    assert!(decode_png(&std::fs::read(&file).unwrap()).width() > 600);
    eprintln!("screenshot: {}", file.display());
}

/// PSNR (dB) of `b` against `a`, values in [0, 1].
fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum::<f64>() / a.len() as f64;
    -10.0 * mse.max(1e-12).log10()
}

#[test]
fn the_gpu_backend_renders_what_the_cpu_renders_across_edits() {
    let ctx = match assetfield_gpu::GpuContext::new() {
        Ok(c) => c,
        Err(assetfield_gpu::GpuError::NoAdapter(reason)) => {
            let msg = format!(
                "SKIPPED: no wgpu adapter ({reason}); the editor's GPU backend was not compared with the CPU"
            );
            assert!(!strict(), "{msg} (ASSETFIELD_STRICT_TESTS is set)");
            eprintln!("{msg}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let lib = library();
    let opts = |name: &str| SessionOptions { layout: Some(lib.join(name)), ..Default::default() };
    let mut cpu = EditSession::open(lib, &opts("gpu_cpu.ron"), None).unwrap();
    let mut gpu = EditSession::open(lib, &opts("gpu_gpu.ron"), Some((ctx, false))).unwrap();
    assert_eq!((cpu.backend(), gpu.backend()), ("cpu", "gpu"));
    let view =
        ViewRequest { width: 64, height: 48, azimuth_deg: 20.0, elevation_deg: 40.0, radius: None };
    let mut last: Option<Vec<f32>> = None;
    for edit in [None, Some("[Move(target: \"w1\", by: (0.4, 0.2))]"), Some("[Remove(\"b1\")]")] {
        if let Some(e) = edit {
            cpu.apply(e).unwrap();
            gpu.apply(e).unwrap();
        }
        let (c, g) = (cpu.render(&view).unwrap(), gpu.render(&view).unwrap());
        let p = psnr(&c, &g);
        assert!(p > 45.0, "{edit:?}: GPU against CPU {p:.1} dB");
        if let Some(prev) = &last {
            assert!(psnr(prev, &g) < 40.0, "{edit:?}: the GPU render did not follow the edit");
        }
        last = Some(g);
    }
}
