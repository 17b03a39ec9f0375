//! A `terrastitch serve` child process and plain-socket requests to it.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::Stdio;
use std::time::Duration;

use super::terrastitch;

/// Starts `serve` on a free port with extra arguments and environment; returns the child, its
/// address, and a channel of its stderr lines after the one that gives the address.
pub fn spawn_server(
    args: &[&str],
    env: &[(&str, &str)],
) -> (
    std::process::Child,
    String,
    std::sync::mpsc::Receiver<String>,
) {
    let mut command = terrastitch();
    command
        .args(["serve", "--listen", "127.0.0.1:0"])
        .args(args);
    for (name, value) in env {
        command.env(name, value);
    }
    let mut child = command.stderr(Stdio::piped()).spawn().unwrap();
    let stderr = child.stderr.take().unwrap();
    let (lines_tx, lines_rx) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if lines_tx.send(line).is_err() {
                return;
            }
        }
    });
    let (address_tx, address_rx) = std::sync::mpsc::channel::<String>();
    let (rest_tx, rest_rx) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        let mut sent = false;
        for line in lines_rx {
            match line.strip_prefix("listening on http://") {
                Some(address) if !sent => {
                    sent = true;
                    let _ = address_tx.send(address.to_string());
                }
                _ => {
                    if rest_tx.send(line).is_err() {
                        return;
                    }
                }
            }
        }
    });
    let address = address_rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the server starts");
    (child, address, rest_rx)
}

/// A GET over a plain socket: the status and the body.
pub fn http_get(address: &str, path: &str) -> (u16, Vec<u8>) {
    let (status, _, body) = request(address, path, &[]);
    (status, body)
}

/// A GET over a plain socket with extra headers: the status, the header block and the body.
/// The value of the unlabelled metric `name` in the `/metrics` of the server at `address`.
pub fn metric(address: &str, name: &str) -> Option<f64> {
    let (_, _, body) = request(address, "/metrics", &[]);
    super::metric_in(&String::from_utf8_lossy(&body), name)
}

pub fn request(address: &str, path: &str, headers: &[(&str, &str)]) -> (u16, String, Vec<u8>) {
    let mut stream = std::net::TcpStream::connect(address).unwrap();
    let extra: String = headers
        .iter()
        .map(|(name, value)| format!("{name}: {value}\r\n"))
        .collect();
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\n{extra}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut response = Vec::new();
    stream.read_to_end(&mut response).unwrap();
    let split = response
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header block");
    let head = String::from_utf8_lossy(&response[..split]).to_string();
    let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    (status, head, response[split + 4..].to_vec())
}
