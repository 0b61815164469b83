//! stripmask on emulated embedded Linux boards: QEMU boots a Debian kernel with an initramfs that
//! holds busybox and a `stripmask` for the board's CPU (on the ARM board a static one that
//! tests/boards/setup.sh cross-built, on the x86 board the suite's own binary with the shared
//! libraries it loads); `stripmask fb` draws a fixed
//! flight on the simulated clock into the kernel's framebuffer driver; the QEMU monitor's
//! `screendump` captures the screen, which must equal, byte for byte in the framebuffer's pixel
//! format, the same frame that `stripmask fly` renders on the host into a PNG. A second run
//! reads an evdev keyboard: keys sent through the monitor (`send-key`) must change the picture
//! exactly as the same commands change it on the host.
//!
//! The boards come from `tests/boards/setup.sh` (Debian packages only; see docs/platforms.md).
//! Without them each board test prints `SKIPPED` and why, and passes — unless the environment
//! says `STRIPMASK_BOARDS=required` (as `.ci/run` does), where a missing board fails.
//! `STRIPMASK_BOARDS_DIR` moves the boards from `target/boards`.
//!
//! Everything here asserts pictures, never timings; the time limits only bound a hung guest.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use image::{ImageBuffer, Luma, RgbImage, RgbaImage};
use stripmask::FrameTiming;
use stripmask::db::archive::ArchiveReader;
use stripmask::engine::EngineSettings;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::sim::clock::{Clock, CostModel};
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::Flight;
use stripmask::sim::viewer::{ViewerOptions, run};
use stripmask_platform::{Command as Key, Input, Overlay, PlatformError, Presenter};
use stripmask_raster::{ColorFormat, Framebuffer};

/// Frames of the fixed flight: enough for the first tiles to arrive and the view to move.
const FLIGHT_FRAMES: u64 = 12;
/// Frames after which the still view of the keyboard run has every tile it will ever have.
const SETTLE_FRAMES: usize = 40;
/// Bounds on a guest that hangs (emulated, cold caches, a busy machine): never asserted.
const BOOT_LIMIT: Duration = Duration::from_secs(300);
const RUN_LIMIT: Duration = Duration::from_secs(600);
/// How long a screen may take to show what a key press leads to (a few frames, each under a
/// second on the slowest board): the bound after which a key counts as lost.
const SCREEN_LIMIT: Duration = Duration::from_secs(180);

// ---- the scene, shared by the host and the boards ---------------------------------------------

/// A 257 x 257 corner of the Puget Sound height map around Mount Rainier as a 16-bit PNG, cut into an archive by the
/// host's `stripmask build`: 4 x 4 tiles of 65 samples, small enough for an initramfs.
fn build_archive(dir: &Path) -> PathBuf {
    let dem = image::open(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png"),
    )
    .expect("the example height map")
    .into_luma16();
    let crop: ImageBuffer<Luma<u16>, Vec<u16>> =
        image::imageops::crop_imm(&dem, 672, 400, 257, 257).to_image();
    let png = dir.join("corner.png");
    crop.save(&png).unwrap();
    let archive = dir.join("terrain.smdb");
    let status = Command::new(env!("CARGO_BIN_EXE_stripmask"))
        .args(["build", "--quiet", "--tile-size", "65", "--spacing", "160"])
        .args(["--vertical-scale", "0.1"])
        .arg(&png)
        .arg("-o")
        .arg(&archive)
        .status()
        .unwrap();
    assert!(status.success(), "stripmask build failed");
    archive
}

/// A flight that stands still over the archive, looking across it: after a few frames every
/// frame is the same, so a key's effect does not depend on the frame it arrives in.
fn still_flight(archive: &Path) -> String {
    let reader =
        ArchiveReader::open(stripmask::db::source::open(archive.to_str().unwrap()).unwrap())
            .unwrap();
    let terrain = TerrainFrame::new(reader.header());
    let (w, d) = terrain.extent();
    let (_, top) = terrain.heights;
    format!(
        "name = \"still\"\n[[key]]\nt = 0.0\nposition = [{}, {}, {}]\nlook_at = [{}, {}, {}]\n",
        0.1 * w,
        top + 0.12 * w.max(d),
        0.95 * d,
        0.6 * w,
        0.0,
        0.35 * d
    )
}

/// The scene arguments `fly` on the host and `fb` on the board share.
fn scene_args(size: (u32, u32), color: &str, flight: &str) -> Vec<String> {
    [
        "--clock",
        "simulated",
        "--profile",
        "native",
        "--size",
        &format!("{}x{}", size.0, size.1),
        "--color",
        color,
        "--flight",
        flight,
    ]
    .map(String::from)
    .to_vec()
}

/// Frame `frames - 1` of `stripmask fly` with `args` over `archive`, rendered on the host.
fn fly_on_host(archive: &Path, out: &Path, frames: u64, args: &[String]) -> RgbaImage {
    let status = Command::new(env!("CARGO_BIN_EXE_stripmask"))
        .arg("fly")
        .arg(archive)
        .args(["--quiet", "--no-plots", "--frames", &frames.to_string()])
        .args(["--every", &(frames - 1).to_string()])
        .arg("--out")
        .arg(out)
        .args(args)
        .status()
        .unwrap();
    assert!(status.success(), "stripmask fly failed");
    image::open(out.join(format!("frames/frame_{:06}.png", frames - 1)))
        .unwrap()
        .to_rgba8()
}

// ---- the host: the viewer on the simulated clock -------------------------------------------------

/// Plays one input per frame and keeps every frame it is shown.
struct Script {
    inputs: VecDeque<Input>,
    shown: Vec<RgbaImage>,
}

impl Presenter for Script {
    fn present(&mut self, frame: &Framebuffer, _: Option<&Overlay>) -> Result<(), PlatformError> {
        self.shown.push(frame.to_rgba_image());
        Ok(())
    }

    fn poll_input(&mut self) -> Input {
        self.inputs.pop_front().unwrap_or_default()
    }
}

/// What `stripmask fb` shows with `--clock simulated --profile native` and these settings: the
/// viewer with the options the CLI gives it, driven by `inputs`, one per frame.
fn viewer_on_host(
    archive: &Path,
    flight: Flight,
    size: (u32, u32),
    color: ColorFormat,
    inputs: Vec<Input>,
) -> Vec<RgbaImage> {
    let p = DeviceProfile::native();
    let clock = Clock::Simulated {
        model: CostModel::HOST,
        slowdown: p.cpu_slowdown,
    };
    let mut engine = EngineSettings {
        memory_limit_bytes: p.memory_limit_bytes(),
        threads: p.threads,
        pager_mode: clock.pager_mode(4),
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    engine.budget.target_fps = p.target_fps;
    engine.budget.expected = Some(clock.expected_cost(size.0, size.1));
    let frames = inputs.len() as u64;
    let mut script = Script {
        inputs: inputs.into(),
        shown: Vec::new(),
    };
    let options = ViewerOptions {
        source: archive.display().to_string(),
        size,
        color,
        depth: p.depth,
        engine,
        hud: false,
        flight,
        frames: Some(frames),
        clock,
        poses: None,
    };
    run(&mut script, &options).unwrap();
    script.shown
}

fn press(key: Key) -> Input {
    Input {
        commands: vec![key],
        ..Input::default()
    }
}

/// The viewer on the simulated clock draws, frame for frame, what `fly` draws: what the board
/// tests rely on when they compare a board's `fb` with a host's `fly`. Needs no board.
#[test]
fn the_simulated_viewer_draws_what_fly_draws() {
    let dir = tempfile::tempdir().unwrap();
    let archive = build_archive(dir.path());
    let reader =
        ArchiveReader::open(stripmask::db::source::open(archive.to_str().unwrap()).unwrap())
            .unwrap();
    let terrain = TerrainFrame::new(reader.header());
    let flight = Flight::builtin(stripmask::sim::flight::Builtin::Diagonal, &terrain);
    let shown = viewer_on_host(
        &archive,
        flight,
        (160, 120),
        ColorFormat::Rgb565,
        vec![Input::default(); FLIGHT_FRAMES as usize],
    );
    let flown = fly_on_host(
        &archive,
        &dir.path().join("fly"),
        FLIGHT_FRAMES,
        &scene_args((160, 120), "rgb565", "diagonal"),
    );
    assert_eq!(shown.len(), FLIGHT_FRAMES as usize);
    assert!(
        shown.last() == Some(&flown),
        "the viewer's last frame differs from fly's in {} pixels",
        differing(shown.last().unwrap(), &flown)
    );
    assert_ne!(shown[0], flown, "the flight moved and tiles arrived");
}

fn differing(a: &RgbaImage, b: &RgbaImage) -> usize {
    a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count()
}

// ---- the boards ------------------------------------------------------------------------------

/// A board set up by tests/boards/setup.sh.
struct Board {
    name: &'static str,
    dir: PathBuf,
    /// The QEMU command line from `qemu-args`, without the initramfs and the I/O.
    qemu: Vec<String>,
    /// Whether the board runs the host's own `stripmask` (appended to the initramfs at boot)
    /// rather than one that tests/boards/setup.sh cross-built into it: setup.sh leaves
    /// `host-binary` in the board's folder when the board is the host's architecture.
    runs_host_binary: bool,
}

fn boards_dir() -> PathBuf {
    std::env::var_os("STRIPMASK_BOARDS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/boards"))
}

impl Board {
    /// The board `name`, or `None` (with `SKIPPED` and the reason on stderr) when it is not set
    /// up; a panic instead when `STRIPMASK_BOARDS=required`.
    fn get(name: &'static str) -> Option<Board> {
        match Board::load(name) {
            Ok(board) => Some(board),
            Err(why) => {
                let required = std::env::var("STRIPMASK_BOARDS").is_ok_and(|v| v == "required");
                assert!(
                    !required,
                    "board {name}: {why} (STRIPMASK_BOARDS=required; run tests/boards/setup.sh)"
                );
                eprintln!("SKIPPED board {name}: {why}; run tests/boards/setup.sh {name}");
                None
            }
        }
    }

    fn load(name: &'static str) -> Result<Board, String> {
        let dir = boards_dir().join(name);
        let args = dir.join("qemu-args");
        let text =
            std::fs::read_to_string(&args).map_err(|e| format!("{}: {e}", args.display()))?;
        let qemu: Vec<String> = text.lines().map(String::from).collect();
        let emulator = qemu.first().ok_or(format!("{} is empty", args.display()))?;
        for path in [Path::new(emulator), &dir.join("initramfs.cpio.gz")] {
            if !path.exists() {
                return Err(format!("{} is missing", path.display()));
            }
        }
        let runs_host_binary = dir.join("host-binary").exists();
        Ok(Board {
            name,
            dir,
            qemu,
            runs_host_binary,
        })
    }
}

/// The screen as the guest's kernel describes it in the `@@ready` line.
#[derive(Clone, Debug)]
struct Screen {
    size: (u32, u32),
    /// Bits of red, green and blue in a pixel.
    bits: [u32; 3],
}

impl Screen {
    /// `fb=NAME:W,H:BPP` from the ready line.
    fn parse(ready: &str) -> Screen {
        let fb = field(ready, "fb").unwrap_or_else(|| panic!("no fb= in {ready:?}"));
        let parts: Vec<&str> = fb.split(':').collect();
        assert_eq!(parts.len(), 3, "no framebuffer on the board: {ready:?}");
        let (w, h) = parts[1].split_once(',').unwrap();
        let bits = match parts[2] {
            "16" => [5, 6, 5],
            "24" | "32" => [8, 8, 8],
            other => panic!("{other} bits per pixel: not a format this test knows"),
        };
        Screen {
            size: (w.parse().unwrap(), h.parse().unwrap()),
            bits,
        }
    }

    /// `rgb` with each channel cut to the screen's bits: what the framebuffer holds of it.
    fn pixel(&self, rgb: [u8; 3]) -> [u8; 3] {
        [0, 1, 2].map(|c| rgb[c] >> (8 - self.bits[c]))
    }

    /// Pixels whose framebuffer values differ between a capture and a host picture.
    fn differing(&self, captured: &RgbImage, expected: &RgbaImage) -> usize {
        assert_eq!(
            captured.dimensions(),
            expected.dimensions(),
            "picture sizes"
        );
        captured
            .pixels()
            .zip(expected.pixels())
            .filter(|(c, e)| self.pixel(c.0) != self.pixel([e[0], e[1], e[2]]))
            .count()
    }
}

fn field<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(name)?.strip_prefix('='))
}

/// A booted board: QEMU with the serial console on its stdin and stdout and QMP on a socket.
struct Machine {
    child: Child,
    stdin: ChildStdin,
    lines: Receiver<String>,
    /// Everything the guest printed, for failure messages.
    log: Arc<Mutex<String>>,
    qmp: BufReader<UnixStream>,
    dir: tempfile::TempDir,
    board: &'static str,
    ready: String,
}

impl Machine {
    /// Boots `board` with its initramfs and `extra` files appended.
    fn boot(board: &Board, extra: &[GuestFile]) -> Machine {
        let dir = tempfile::tempdir().unwrap();
        let initrd = dir.path().join("initramfs");
        let mut bytes = std::fs::read(board.dir.join("initramfs.cpio.gz")).unwrap();
        // The kernel reads concatenated archives, each starting on a 4-byte boundary.
        bytes.resize(bytes.len().next_multiple_of(4), 0);
        bytes.extend(newc(extra));
        std::fs::write(&initrd, bytes).unwrap();
        let socket = dir.path().join("qmp");
        let started = Instant::now();
        let mut child = Command::new(&board.qemu[0])
            .args(&board.qemu[1..])
            .arg("-initrd")
            .arg(&initrd)
            .args(["-display", "none", "-monitor", "none", "-serial", "stdio"])
            .args(["-nic", "none", "-no-reboot"])
            .arg("-qmp")
            .arg(format!("unix:{},server=on,wait=off", socket.display()))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", board.qemu[0]));
        let log = Arc::new(Mutex::new(String::new()));
        let (tx, lines) = mpsc::channel();
        let stdout = child.stdout.take().unwrap();
        let sink = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                let line = line.trim_end_matches('\r').to_string();
                sink.lock().unwrap().push_str(&format!("{line}\n"));
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = child.stderr.take().unwrap();
        let sink = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                sink.lock().unwrap().push_str(&format!("qemu: {line}\n"));
            }
        });
        let stdin = child.stdin.take().unwrap();
        let qmp = qmp_connect(&socket, &mut child);
        let mut machine = Machine {
            child,
            stdin,
            lines,
            log,
            qmp,
            dir,
            board: board.name,
            ready: String::new(),
        };
        machine.ready = machine.wait_for("@@ready", BOOT_LIMIT);
        eprintln!(
            "{}: booted in {:.1} s: {}",
            board.name,
            started.elapsed().as_secs_f64(),
            machine.ready
        );
        machine
    }

    /// The next serial line holding `marker`, from the marker on (a shell prompt may stand
    /// before it); panics with the guest's output after `limit`.
    fn wait_for(&mut self, marker: &str, limit: Duration) -> String {
        let deadline = Instant::now() + limit;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if line.contains(marker) => {
                    return line[line.find(marker).unwrap()..].to_string();
                }
                Ok(_) => {}
                Err(RecvTimeoutError::Timeout) => {
                    self.fail(&format!("no {marker:?} within {limit:?}"))
                }
                Err(RecvTimeoutError::Disconnected) => {
                    let status = self.child.wait();
                    self.fail(&format!("QEMU ended ({status:?}) before {marker:?}"))
                }
            }
        }
    }

    fn fail(&self, what: &str) -> ! {
        panic!(
            "{}: {what}; the guest said:\n{}",
            self.board,
            self.log.lock().unwrap()
        )
    }

    /// Types `command` into the guest's shell.
    fn send(&mut self, command: &str) {
        writeln!(self.stdin, "{command}").unwrap();
        self.stdin.flush().unwrap();
    }

    /// Runs `command` in the guest's shell and returns what it printed to the serial console,
    /// failing unless it exits 0.
    fn run(&mut self, command: &str) -> String {
        let started = Instant::now();
        self.send(&format!("{command}; echo @@done $?"));
        let mut printed = String::new();
        let deadline = Instant::now() + RUN_LIMIT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if line.contains("@@done ") => {
                    let (before, done) = line.split_at(line.find("@@done ").unwrap());
                    printed.push_str(before);
                    if done != "@@done 0" {
                        self.fail(&format!("`{command}` failed ({done}): {printed}"));
                    }
                    eprintln!(
                        "{}: `{command}` took {:.1} s: {}",
                        self.board,
                        started.elapsed().as_secs_f64(),
                        printed.trim()
                    );
                    return printed;
                }
                Ok(line) => printed.push_str(&format!("{line}\n")),
                Err(_) => self.fail(&format!("`{command}` did not finish in {RUN_LIMIT:?}")),
            }
        }
    }

    /// One QMP command; its `return` value.
    fn qmp(&mut self, command: serde_json::Value) -> serde_json::Value {
        let mut text = command.to_string();
        text.push('\n');
        self.qmp.get_mut().write_all(text.as_bytes()).unwrap();
        qmp_reply(&mut self.qmp).unwrap_or_else(|e| self.fail(&format!("QMP {command}: {e}")))
    }

    /// The screen as QEMU shows it (`screendump`), 8 bits per channel.
    fn screendump(&mut self) -> RgbImage {
        let path = self.dir.path().join("screen.ppm");
        self.qmp(serde_json::json!({
            "execute": "screendump",
            "arguments": { "filename": path.to_str().unwrap() }
        }));
        read_ppm(&std::fs::read(&path).unwrap())
    }

    /// The screen once it has stopped changing: two captures in a row, `gap` apart, equal.
    fn settled_screen(&mut self, gap: Duration) -> RgbImage {
        let deadline = Instant::now() + RUN_LIMIT;
        let mut last = self.screendump();
        loop {
            std::thread::sleep(gap);
            let now = self.screendump();
            if now == last {
                return now;
            }
            if Instant::now() > deadline {
                self.fail("the screen never stopped changing");
            }
            last = now;
        }
    }

    /// Polls the screen until it shows `expected` (in the framebuffer's format): the picture a
    /// key press must lead to. Fails, with the number of differing pixels, if it never does.
    fn wait_for_screen(&mut self, screen: &Screen, expected: &RgbaImage, what: &str) -> RgbImage {
        let deadline = Instant::now() + SCREEN_LIMIT;
        loop {
            let now = self.screendump();
            let off = screen.differing(&now, expected);
            if off == 0 {
                return now;
            }
            if Instant::now() > deadline {
                let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/board-failures");
                std::fs::create_dir_all(&keep).unwrap();
                now.save(keep.join(format!("{}-{what}.png", self.board)))
                    .unwrap();
                expected
                    .save(keep.join(format!("{}-{what}-expected.png", self.board)))
                    .unwrap();
                self.fail(&format!(
                    "{what}: the screen still differs from the host's picture in {off} pixels \
                     (both in {})",
                    keep.display()
                ));
            }
            std::thread::sleep(Duration::from_millis(500));
        }
    }

    fn send_key(&mut self, qcode: &str) {
        self.qmp(serde_json::json!({
            "execute": "send-key",
            "arguments": { "keys": [ { "type": "qcode", "data": qcode } ] }
        }));
    }
}

impl Drop for Machine {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn qmp_connect(socket: &Path, child: &mut Child) -> BufReader<UnixStream> {
    let deadline = Instant::now() + Duration::from_secs(60);
    let stream = loop {
        match UnixStream::connect(socket) {
            Ok(s) => break s,
            Err(e) => {
                if let Ok(Some(status)) = child.try_wait() {
                    let mut err = String::new();
                    child.stderr.take().map(|mut s| s.read_to_string(&mut err));
                    panic!("QEMU exited ({status}) before its monitor opened: {err}");
                }
                assert!(
                    Instant::now() < deadline,
                    "QMP socket {}: {e}",
                    socket.display()
                );
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    };
    let mut qmp = BufReader::new(stream);
    let mut greeting = String::new();
    qmp.read_line(&mut greeting).unwrap();
    assert!(greeting.contains("QMP"), "not a QMP greeting: {greeting}");
    qmp.get_mut()
        .write_all(b"{\"execute\":\"qmp_capabilities\"}\n")
        .unwrap();
    qmp_reply(&mut qmp).unwrap();
    qmp
}

/// The next reply on a QMP connection, skipping events.
fn qmp_reply(qmp: &mut BufReader<UnixStream>) -> Result<serde_json::Value, String> {
    loop {
        let mut line = String::new();
        if qmp.read_line(&mut line).map_err(|e| e.to_string())? == 0 {
            return Err("the monitor closed".into());
        }
        let v: serde_json::Value =
            serde_json::from_str(&line).map_err(|e| format!("{e}: {line}"))?;
        if let Some(r) = v.get("return") {
            return Ok(r.clone());
        }
        if let Some(e) = v.get("error") {
            return Err(e.to_string());
        }
    }
}

/// A binary PPM (P6, maxval 255), as QEMU's screendump writes it.
fn read_ppm(bytes: &[u8]) -> RgbImage {
    let mut fields = Vec::new();
    let mut at = 0;
    while fields.len() < 4 {
        while bytes[at].is_ascii_whitespace() {
            at += 1;
        }
        let start = at;
        while !bytes[at].is_ascii_whitespace() {
            at += 1;
        }
        fields.push(std::str::from_utf8(&bytes[start..at]).unwrap().to_string());
    }
    assert_eq!((fields[0].as_str(), fields[3].as_str()), ("P6", "255"));
    let (w, h) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    RgbImage::from_raw(w, h, bytes[at + 1..].to_vec()).expect("PPM pixel data")
}

/// A file the test adds to a board's initramfs: its path from the root, its mode, its bytes.
struct GuestFile {
    path: String,
    mode: u32,
    data: Vec<u8>,
}

impl GuestFile {
    /// A data file under /data (the archive, a flight).
    fn data(name: &str, data: Vec<u8>) -> GuestFile {
        GuestFile {
            path: format!("data/{name}"),
            mode: 0o644,
            data,
        }
    }
}

/// The host's `stripmask` as /usr/bin/stripmask, with the shared libraries `ldd` says it loads
/// at their host paths: on a board of the host's architecture the suite's own binary runs
/// unchanged, and the board needs no build of its own.
fn host_binary() -> Vec<GuestFile> {
    let binary = env!("CARGO_BIN_EXE_stripmask");
    let read = |path: &str| std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let ldd = Command::new("ldd")
        .arg(binary)
        .output()
        .unwrap_or_else(|e| panic!("ldd {binary}: {e}"));
    assert!(ldd.status.success(), "ldd {binary}: {:?}", ldd.status);
    let mut files = vec![GuestFile {
        path: "usr/bin/stripmask".into(),
        mode: 0o755,
        data: read(binary),
    }];
    for line in String::from_utf8_lossy(&ldd.stdout).lines() {
        // `libc.so.6 => /lib/x86_64-linux-gnu/libc.so.6 (0x...)` or `/lib64/ld-linux-x86-64.so.2 (0x...)`;
        // the vDSO has no path.
        let Some(path) = line.split_whitespace().find(|word| word.starts_with('/')) else {
            continue;
        };
        files.push(GuestFile {
            path: path.trim_start_matches('/').into(),
            mode: 0o755,
            data: read(path),
        });
    }
    files
}

/// An uncompressed cpio archive (the kernel's "newc" format) of `files`, with a directory entry
/// for every folder above them (the kernel keeps a folder that is already there).
fn newc(files: &[GuestFile]) -> Vec<u8> {
    fn entry(out: &mut Vec<u8>, ino: usize, name: &str, mode: u32, data: &[u8]) {
        let header = format!(
            "070701{ino:08x}{mode:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}{:08x}",
            0,
            0,
            1,
            0,
            data.len(),
            0,
            0,
            0,
            0,
            name.len() + 1,
            0
        );
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.resize(out.len().next_multiple_of(4), 0);
        out.extend_from_slice(data);
        out.resize(out.len().next_multiple_of(4), 0);
    }
    let folders: std::collections::BTreeSet<&str> = files
        .iter()
        .flat_map(|file| Path::new(&file.path).ancestors().skip(1))
        .filter_map(|folder| folder.to_str())
        .filter(|folder| !folder.is_empty())
        .collect();
    let mut out = Vec::new();
    let mut ino = 0;
    for folder in folders {
        ino += 1;
        entry(&mut out, ino, folder, 0o040755, &[]);
    }
    for file in files {
        ino += 1;
        entry(&mut out, ino, &file.path, 0o100000 | file.mode, &file.data);
    }
    entry(&mut out, 0, "TRAILER!!!", 0, &[]);
    out
}

// ---- what every board does -----------------------------------------------------------------

/// With `STRIPMASK_BOARDS_SCREENSHOTS=DIR`, writes a capture at half size (every second pixel of
/// every second row, as captured) to `DIR/NAME.png`: the pictures in docs/.
fn screenshot(captured: &RgbImage, name: &str) {
    let Some(dir) = std::env::var_os("STRIPMASK_BOARDS_SCREENSHOTS") else {
        return;
    };
    let (w, h) = captured.dimensions();
    let half = RgbImage::from_fn(w / 2, h / 2, |x, y| *captured.get_pixel(2 * x, 2 * y));
    let file = std::fs::File::create(Path::new(&dir).join(format!("{name}.png"))).unwrap();
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        std::io::BufWriter::new(file),
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    half.write_with_encoder(encoder).unwrap();
}

/// The fixed flight on the board's framebuffer against the host's PNG, then the keyboard.
fn board_test(name: &'static str, color: &str) {
    let Some(board) = Board::get(name) else {
        return;
    };
    let work = tempfile::tempdir().unwrap();
    let archive = build_archive(work.path());
    let still = still_flight(&archive);
    let mut files = vec![
        GuestFile::data("terrain.smdb", std::fs::read(&archive).unwrap()),
        GuestFile::data("still.toml", still.clone().into_bytes()),
    ];
    if board.runs_host_binary {
        files.extend(host_binary());
    }
    let mut machine = Machine::boot(&board, &files);
    let screen = Screen::parse(&machine.ready);
    let color_format = match color {
        "rgb565" => ColorFormat::Rgb565,
        _ => ColorFormat::Rgba8888,
    };

    // 1. The fixed flight, drawn straight into the board's screen memory (`--in-place`), against
    //    the host's PNG: the screen keeps the last frame, whole, when the run ends.
    let args = scene_args(screen.size, color, "diagonal");
    let expected = fly_on_host(&archive, &work.path().join("fly"), FLIGHT_FRAMES, &args);
    let colours: std::collections::HashSet<[u8; 4]> = expected.pixels().map(|p| p.0).collect();
    assert!(
        colours.len() > 100,
        "the host's frame shows terrain, not a blank screen ({} colours)",
        colours.len()
    );
    machine.run(&format!(
        "stripmask fb /data/terrain.smdb --no-hud --in-place --frames {FLIGHT_FRAMES} {}",
        args.join(" ")
    ));
    let captured = machine.settled_screen(Duration::from_millis(300));
    let off = screen.differing(&captured, &expected);
    if off != 0 {
        let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/board-failures");
        std::fs::create_dir_all(&keep).unwrap();
        captured
            .save(keep.join(format!("{name}-flight.png")))
            .unwrap();
        expected
            .save(keep.join(format!("{name}-flight-expected.png")))
            .unwrap();
        panic!(
            "{name}: the board's frame differs from the host's in {off} of {} pixels (pictures in {})",
            captured.len() / 3,
            keep.display()
        );
    }
    screenshot(&captured, &format!("board-{name}"));

    // 2. The keyboard: the still view settles, then L (wireframe over the terrain) and K (the
    //    next crack mode) change it exactly as they change it on the host.
    let keyboard = field(&machine.ready, "keyboard")
        .filter(|k| *k != "none")
        .unwrap_or_else(|| machine.fail("the board has no keyboard"))
        .to_string();
    let flight = Flight::from_toml(&{
        let path = work.path().join("still.toml");
        std::fs::write(&path, &still).unwrap();
        path
    })
    .unwrap();
    let idle = |n: usize| vec![Input::default(); n];
    let host = |inputs: Vec<Input>| {
        viewer_on_host(&archive, flight.clone(), screen.size, color_format, inputs)
            .pop()
            .unwrap()
    };
    let settled = host(idle(SETTLE_FRAMES));
    let wire = host([idle(SETTLE_FRAMES), vec![press(Key::Wireframe)], idle(3)].concat());
    let cracks = host(
        [
            idle(SETTLE_FRAMES),
            vec![press(Key::Wireframe)],
            idle(3),
            vec![press(Key::CrackMode)],
            idle(SETTLE_FRAMES),
        ]
        .concat(),
    );
    assert_ne!(settled, wire, "L changes the picture on the host");
    assert_ne!(wire, cracks, "K changes the picture on the host");

    machine.send(&format!(
        "stripmask fb /data/terrain.smdb --no-hud --input {keyboard} {}; echo @@done $?",
        scene_args(screen.size, color, "/data/still.toml").join(" ")
    ));
    machine.wait_for_screen(&screen, &settled, "still");
    machine.send_key("l");
    let wired = machine.wait_for_screen(&screen, &wire, "wireframe");
    if name == "vexpress-a9" {
        screenshot(&wired, &format!("board-{name}-wireframe"));
    }
    machine.send_key("k");
    machine.wait_for_screen(&screen, &cracks, "crack-mode");
    machine.send_key("esc");
    let done = machine.wait_for("@@done", RUN_LIMIT);
    assert_eq!(done, "@@done 0", "Esc ends stripmask fb normally");
}

/// The Versatile Express with a Cortex-A9 (32-bit ARM, hard float) and its PL111 colour LCD
/// controller at 640x480 RGB565: a classic embedded LCD, the kernel's own framebuffer driver.
#[test]
fn vexpress_a9_pl111_lcd_shows_the_hosts_frames() {
    board_test("vexpress-a9", "rgb565");
}

/// A PC with the VESA BIOS framebuffer (vesafb) at 800x600 and 24 bits per pixel (BGR byte
/// order): the frame is rendered in RGBA8888 and packed into 3 bytes per pixel.
#[test]
fn x86_vesa_framebuffer_shows_the_hosts_frames() {
    board_test("x86-vesa", "rgba8888");
}
