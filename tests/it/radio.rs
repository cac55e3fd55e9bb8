//! A vehicle over a serial line: emplan's `serial:DEVICE:BAUD` link, to the mock autopilot behind
//! a pseudo-terminal (the ground end a telemetry radio's USB adapter gives), uploads and verifies,
//! and flies with every leg measured. The pseudo-terminal is relayed to the mock's UDP port frame
//! by frame, as a radio modem carries whole MAVLink frames. The radio's rate and latency are
//! CI's (`sitl/radio-fly.sh`, in real time); here the line only has to be a serial device.

use std::io::{Read, Write};
use std::net::UdpSocket;
use std::os::fd::{FromRawFd, OwnedFd};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use serde_json::Value;

use crate::service::Reaped;

/// A pseudo-terminal's two ends (the master, the device path of the slave) and the slave kept
/// open, so the master does not read end-of-file between the ground station's opens.
struct Pty {
    master: std::fs::File,
    device: String,
    _slave: OwnedFd,
}

fn pty() -> Pty {
    let (mut master, mut slave) = (0, 0);
    // SAFETY: openpty writes two descriptors into the integers given; the name, termios and
    // window-size arguments may be null.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    assert_eq!(rc, 0, "openpty: {}", std::io::Error::last_os_error());
    // SAFETY: both descriptors were just opened by openpty and are owned here alone.
    let (master, slave) = unsafe { (OwnedFd::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
    let device = std::fs::read_link(format!("/proc/self/fd/{}", raw(&slave)))
        .expect("the slave's device path")
        .to_string_lossy()
        .into_owned();
    // Raw: no echo, no line discipline between the frames.
    // SAFETY: a zeroed termios is a valid argument to tcgetattr, which fills it.
    let mut attrs: libc::termios = unsafe { std::mem::zeroed() };
    // SAFETY: the slave descriptor is open; attrs is a valid termios.
    unsafe {
        assert_eq!(libc::tcgetattr(raw(&slave), &mut attrs), 0);
        libc::cfmakeraw(&mut attrs);
        assert_eq!(libc::tcsetattr(raw(&slave), libc::TCSANOW, &attrs), 0);
    }
    // SAFETY: the master descriptor is open; O_NONBLOCK on it lets the relay stop and drop a
    // frame nobody reads, as a radio whose buffer is full does.
    unsafe {
        let flags = libc::fcntl(raw(&master), libc::F_GETFL);
        assert_eq!(
            libc::fcntl(raw(&master), libc::F_SETFL, flags | libc::O_NONBLOCK),
            0
        );
    }
    Pty {
        master: std::fs::File::from(master),
        device,
        _slave: slave,
    }
}

fn raw(fd: &OwnedFd) -> i32 {
    use std::os::fd::AsRawFd;
    fd.as_raw_fd()
}

/// The length of the MAVLink frame at the start of `buf` (v1 or v2, signed or not), or None
/// until its header has arrived.
fn frame_len(buf: &[u8]) -> Option<usize> {
    match buf {
        [0xFE, len, ..] => Some(usize::from(*len) + 8),
        [0xFD, len, flags, ..] => {
            Some(usize::from(*len) + 12 + if flags & 1 == 1 { 13 } else { 0 })
        }
        _ => None,
    }
}

/// Relays the pseudo-terminal to the mock's UDP port, whole frames each way, until `stop`;
/// counts the frames carried up and down.
fn relay(pty: &Pty, mock_port: u16, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<(u64, u64)> {
    let mut from_ground = pty.master.try_clone().expect("the master, to read");
    let mut to_ground = pty.master.try_clone().expect("the master, to write");
    let udp = UdpSocket::bind("127.0.0.1:0").expect("a UDP socket");
    udp.connect(("127.0.0.1", mock_port))
        .expect("the mock's port");
    udp.set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let udp_up = udp.try_clone().expect("the socket, to send");
    let up_stop = stop.clone();
    let up = std::thread::spawn(move || {
        let (mut pending, mut buf, mut frames) = (Vec::new(), [0u8; 4096], 0u64);
        while !up_stop.load(Ordering::Relaxed) {
            let n = match from_ground.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                }
                Err(_) => break,
            };
            pending.extend_from_slice(&buf[..n]);
            loop {
                let start = pending.iter().position(|b| *b == 0xFD || *b == 0xFE);
                pending.drain(..start.unwrap_or(pending.len()));
                match frame_len(&pending) {
                    Some(len) if pending.len() >= len => {
                        let frame: Vec<u8> = pending.drain(..len).collect();
                        let _ = udp_up.send(&frame);
                        frames += 1;
                    }
                    _ => break,
                }
            }
        }
        frames
    });
    std::thread::spawn(move || {
        let (mut buf, mut down) = ([0u8; 65536], 0u64);
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = udp.recv(&mut buf) {
                if to_ground.write_all(&buf[..n]).is_ok() {
                    down += 1;
                }
            }
        }
        (up.join().unwrap_or(0), down)
    })
}

fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("a free port")
        .port()
}

/// Starts `emplan mock-autopilot` on `port` with `extra` options.
fn mock(port: u16, extra: &[&str]) -> Reaped {
    let listen = format!("udpin:127.0.0.1:{port}");
    let mut args = vec!["mock-autopilot", "--listen", &listen, "--quiet"];
    args.extend_from_slice(extra);
    Reaped(
        std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("emplan mock-autopilot runs"),
    )
}

#[test]
fn an_upload_over_a_serial_device_is_verified_by_read_back() {
    let port = free_udp_port();
    let _mock = mock(port, &[]);
    let line = pty();
    let stop = Arc::new(AtomicBool::new(false));
    let relayed = relay(&line, port, stop.clone());
    let connect = format!("serial:{}:57600", line.device);
    let (ok, stdout, stderr) = crate::emplan(&[
        "upload",
        "missions/paper-sample-8wp.toml",
        "--connect",
        &connect,
        "--json",
    ]);
    stop.store(true, Ordering::Relaxed);
    let (_, down) = relayed.join().expect("the relay ends");
    assert!(ok, "{stdout}\n{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("the upload document");
    assert_eq!(doc["report"]["verified"], true, "{doc}");
    assert!(down > 0, "nothing came down the line");
}

#[test]
fn a_flight_over_a_serial_device_measures_every_leg() {
    let port = free_udp_port();
    let _mock = mock(port, &["--vehicle", "models/s1000", "--speedup", "20"]);
    let line = pty();
    let stop = Arc::new(AtomicBool::new(false));
    let relayed = relay(&line, port, stop.clone());
    let work = tempfile::tempdir().unwrap();
    let mission = crate::generated_mission(work.path(), 3, 40, 10, 11);
    let logs = work.path().join("flights");
    let connect = format!("serial:{}:57600", line.device);
    let (ok, stdout, stderr) = crate::emplan(&[
        "fly",
        &mission,
        "--connect",
        &connect,
        "--arm",
        "--log-dir",
        logs.to_str().unwrap(),
        "--json",
    ]);
    stop.store(true, Ordering::Relaxed);
    relayed.join().expect("the relay ends");
    assert!(ok, "{stdout}\n{stderr}");
    let report: Value = serde_json::from_str(&stdout).expect("the flight report");
    assert_eq!(report["complete"], true, "{report}");
    let legs = report["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 4, "{report}");
    for leg in legs {
        assert!(leg["measured_kj"].is_number(), "{leg}");
        let flags = leg["flags"].as_array().expect("flags");
        assert!(!flags.iter().any(|f| f == "telemetry_gap"), "{leg}");
    }
    assert!(Path::new(report["log_dir"].as_str().unwrap())
        .join("flight.tlog")
        .exists());
}
