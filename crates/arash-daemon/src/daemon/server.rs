//! The operator's socket: one JSON request per line, answered on the same connection, and the
//! tokio loop's housekeeping (signals, systemd, what the control thread hands back).

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::UnixListener;

use crate::config::DaemonConfig;
use crate::ctl::CtlRequest;

use super::requests::{handle, Operator};
use crate::rt::cycle::Garbage;

/// The tokio side: socket, housekeeping, signals, systemd.
pub(super) async fn serve(
    config: &DaemonConfig,
    operator: Arc<Operator>,
    garbage: &mut rtrb::Consumer<Garbage>,
    realtime: bool,
) -> anyhow::Result<()> {
    let socket = &config.socket.path;
    if let Some(dir) = socket.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    if std::os::unix::net::UnixStream::connect(socket).is_ok() {
        anyhow::bail!("another daemon is already listening on {}", socket.display());
    }
    let _ = std::fs::remove_file(socket); // left by a crash
    let listener = UnixListener::bind(socket).with_context(|| format!("binding {}", socket.display()))?;
    let mode = config.socket.mode_bits().expect("validated");
    std::fs::set_permissions(socket, std::os::unix::fs::PermissionsExt::from_mode(mode))?;
    eprintln!("arash-daemon: listening on {} (mode {:o}); motors disabled", socket.display(), mode);

    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
    let mut interrupt = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())?;
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    let started = Instant::now();
    let startup_timeout = Duration::from_secs_f64(config.link.startup_timeout_ms / 1000.0);
    let watchdog = sd_notify::watchdog_enabled();
    let mut ready = false;
    let mut last_beat = (0u64, Instant::now());
    let result = loop {
        tokio::select! {
            _ = term.recv() => { eprintln!("arash-daemon: SIGTERM, stopping"); break Ok(()) }
            _ = interrupt.recv() => { eprintln!("arash-daemon: SIGINT, stopping"); break Ok(()) }
            accepted = listener.accept() => {
                if let Ok((stream, _)) = accepted {
                    tokio::spawn(client(stream, operator.clone()));
                }
            }
            _ = tick.tick() => {
                while let Ok(g) = garbage.pop() { drop(g); }
                let shared = &operator.shared;
                if !shared.running.load(Ordering::Acquire) && ready {
                    break Err(anyhow::anyhow!("the control thread stopped"));
                }
                if !ready {
                    if shared.have_telemetry.load(Ordering::Relaxed) && shared.running.load(Ordering::Acquire) {
                        ready = true;
                        eprintln!("arash-daemon: first telemetry after {:.0} ms; ready{}",
                            started.elapsed().as_secs_f64() * 1e3,
                            if realtime { "" } else { " (without real-time scheduling)" });
                        let _ = sd_notify::notify(&[sd_notify::NotifyState::Ready]);
                    } else if started.elapsed() > startup_timeout {
                        break Err(anyhow::anyhow!(
                            "no valid telemetry from the motor link within link.startup_timeout_ms = {} ms \
                             (link.port = {}); motors were never enabled",
                            config.link.startup_timeout_ms, config.link.port));
                    }
                }
                // The watchdog is fed only while the control loop's heartbeat advances.
                if let Some(period) = watchdog {
                    let beat = shared.cycle.load(Ordering::Acquire);
                    if beat != last_beat.0 && last_beat.1.elapsed() >= period / 2 {
                        let _ = sd_notify::notify(&[sd_notify::NotifyState::Watchdog]);
                        last_beat = (beat, Instant::now());
                    }
                }
            }
        }
    };
    let _ = std::fs::remove_file(socket);
    result
}

/// Longest request line the control socket reads; a longer one is refused and the connection
/// closed, so that a client cannot make the daemon buffer without bound.
pub const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// One operator connection: a JSON request per line, a JSON answer per line. Only complete lines
/// are requests: a client that disconnects mid-line has asked for nothing.
async fn client(stream: tokio::net::UnixStream, operator: Arc<Operator>) {
    use tokio::io::AsyncReadExt;
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read);
    let mut line = Vec::new();
    loop {
        line.clear();
        let limit = MAX_REQUEST_BYTES as u64 + 1;
        match (&mut reader).take(limit).read_until(b'\n', &mut line).await {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
        let complete = line.last() == Some(&b'\n');
        if !complete && line.len() <= MAX_REQUEST_BYTES {
            return; // end of stream in the middle of a line
        }
        let answer = if complete {
            answer(&operator, &line).await
        } else {
            serde_json::json!({ "ok": false, "error": format!("request longer than {MAX_REQUEST_BYTES} bytes; closing") })
        };
        let mut text = answer.to_string();
        text.push('\n');
        if write.write_all(text.as_bytes()).await.is_err() || !complete {
            return;
        }
    }
}

/// The answer to one request line.
async fn answer(operator: &Operator, line: &[u8]) -> serde_json::Value {
    let request = std::str::from_utf8(line)
        .map_err(|_| "bad request: not UTF-8".to_string())
        .and_then(|text| serde_json::from_str::<CtlRequest>(text).map_err(|e| format!("bad request: {e}")));
    match request {
        Ok(request) => match handle(operator, request).await {
            Ok(mut value) => {
                value["ok"] = true.into();
                value
            }
            Err(e) => serde_json::json!({ "ok": false, "error": format!("{e:#}") }),
        },
        Err(e) => serde_json::json!({ "ok": false, "error": e }),
    }
}
