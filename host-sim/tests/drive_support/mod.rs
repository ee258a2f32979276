//! The simulated drive on an ephemeral TCP port in a thread (fast pacing,
//! commissioned), for tests that talk to it through the host tool's client.
//! Dropping it stops the drive and reports how its thread ended.

use host_sim::config::RigConfig;
use host_sim::drive::{self, DriveOptions, Pace, StopFlag};
use host_sim::tool::client::{Client, Endpoint};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Duration;

pub struct Drive {
    pub addr: SocketAddr,
    stop: StopFlag,
    thread: Option<std::thread::JoinHandle<anyhow::Result<()>>>,
}

impl Drive {
    /// The nominal rig, its parameter store in `store` (none: in memory).
    pub fn start(store: Option<PathBuf>) -> Self {
        Self::start_rig(RigConfig::nominal().unwrap(), store, 0.25)
    }

    /// A drive of `rig` (a unit other than the rig file's), the rod at
    /// `position_m`.
    pub fn start_rig(rig: RigConfig, store: Option<PathBuf>, position_m: f64) -> Self {
        let mut o = DriveOptions::new(rig);
        o.initial_position_m = position_m;
        o.pace = Pace::Fast;
        o.commissioned = true;
        o.store = store;
        // Lock-step holds a stream's timeline whatever the host's load, up
        // to this wall-clock stall of the client (the default 0.25 s was
        // exceeded by a test thread descheduled on a loaded 2-core CI
        // machine: the stream then ran free and the tracking test failed).
        o.stream_idle_s = 2.0;
        let (addr, stop, h) = drive::spawn_local(o).unwrap();
        Self { addr, stop, thread: Some(h) }
    }

    pub fn connect(&self) -> Client {
        Client::connect(&Endpoint::Tcp(self.addr.to_string())).unwrap()
    }

    /// A client that skips the schema check, with a short read timeout.
    #[allow(dead_code)]
    pub fn raw(&self) -> Client {
        let s = std::net::TcpStream::connect(self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
        Client::raw(Box::new(s))
    }
}

impl Drop for Drive {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.thread.take() {
            h.join().unwrap().unwrap();
        }
    }
}
