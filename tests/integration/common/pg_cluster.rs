//! A throwaway PostgreSQL cluster for tests: `initdb` into a temporary directory, a server on
//! a free loopback port with trust authentication and its socket in that directory, stopped
//! and removed when dropped. PostgreSQL refuses to run as root: a test run as root runs the
//! server as the unprivileged user [`USER`] (`make test` installs Debian's `postgresql` when
//! it is missing and creates that user).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The unprivileged user the server runs as when the tests run as root.
pub const USER: &str = "terrastitch-pg";

pub struct Cluster {
    dir: tempfile::TempDir,
    bin: PathBuf,
    as_user: Option<String>,
    pub port: u16,
}

/// The directory of PostgreSQL's server programs: Debian's newest version, else the PATH's.
fn server_bin() -> PathBuf {
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let version = entry.file_name().to_str()?.parse::<u32>().ok()?;
            let bin = entry.path().join("bin");
            bin.join("initdb").exists().then_some((version, bin))
        })
        .collect();
    versions.sort();
    if let Some((_, bin)) = versions.pop() {
        return bin;
    }
    let found = Command::new("sh")
        .args(["-c", "command -v initdb"])
        .output()
        .expect("a shell");
    let path = String::from_utf8_lossy(&found.stdout).trim().to_string();
    assert!(
        !path.is_empty(),
        "PostgreSQL's server programs are not installed: run `make test` (it installs Debian's postgresql)"
    );
    Path::new(&path)
        .parent()
        .expect("a directory")
        .to_path_buf()
}

impl Cluster {
    /// Starts a new, empty cluster.
    pub fn start() -> Cluster {
        let bin = server_bin();
        let dir = tempfile::tempdir().expect("a temporary directory");
        // SAFETY: geteuid has no preconditions and cannot fail.
        let root = unsafe { libc::geteuid() } == 0;
        let as_user = root.then(|| USER.to_string());
        if root {
            let id = Command::new("id").args(["-u", USER]).output().expect("id");
            let uid: u32 = String::from_utf8_lossy(&id.stdout)
                .trim()
                .parse()
                .unwrap_or_else(|_| {
                    panic!("no user {USER} to run PostgreSQL as: run `make test` (it creates it)")
                });
            std::os::unix::fs::chown(dir.path(), Some(uid), None).expect("chown");
        }
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let cluster = Cluster {
            dir,
            bin,
            as_user,
            port,
        };
        let data = cluster.dir.path().join("data");
        cluster.run(
            "initdb",
            &[
                "-D".as_ref(),
                data.as_os_str(),
                "-U".as_ref(),
                "postgres".as_ref(),
                "--auth=trust".as_ref(),
                "--no-sync".as_ref(),
                "-E".as_ref(),
                "UTF8".as_ref(),
                "--locale=C".as_ref(),
            ],
        );
        let options = format!(
            "-p {port} -k {} -c listen_addresses=127.0.0.1 -c fsync=off -c synchronous_commit=off -c full_page_writes=off",
            cluster.dir.path().display()
        );
        let log = cluster.dir.path().join("server.log");
        cluster.run(
            "pg_ctl",
            &[
                "-D".as_ref(),
                data.as_os_str(),
                "-o".as_ref(),
                options.as_ref(),
                "-l".as_ref(),
                log.as_os_str(),
                "-w".as_ref(),
                "start".as_ref(),
            ],
        );
        cluster
    }

    /// One of the server's programs, run as the cluster's user.
    fn command(&self, program: &str) -> Command {
        let path = self.bin.join(program);
        match &self.as_user {
            Some(user) => {
                let mut c = Command::new("runuser");
                c.args(["-u", user, "--"]).arg(&path);
                c
            }
            None => Command::new(&path),
        }
    }

    fn run(&self, program: &str, args: &[&std::ffi::OsStr]) {
        let output = self
            .command(program)
            .args(args)
            .current_dir(self.dir.path())
            .output()
            .unwrap_or_else(|e| panic!("{program}: {e}"));
        assert!(
            output.status.success(),
            "{program} failed: {}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
    }

    /// The URL of database `name` on this cluster.
    pub fn url(&self, name: &str) -> String {
        format!("postgres://postgres@127.0.0.1:{}/{name}", self.port)
    }

    /// Creates an empty database and gives its URL.
    pub fn database(&self, name: &str) -> String {
        let mut admin = postgres::Client::connect(&self.url("postgres"), postgres::NoTls)
            .expect("connecting to the test cluster");
        admin
            .batch_execute(&format!("CREATE DATABASE {name}"))
            .expect("creating a database");
        self.url(name)
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let data = self.dir.path().join("data");
        let _ = self
            .command("pg_ctl")
            .args(["-D".as_ref(), data.as_os_str()])
            .args(["-m", "immediate", "-w", "stop"])
            .output();
    }
}
