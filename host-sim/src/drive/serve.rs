//! The simulated drive on a TCP socket: any number of clients at once, one
//! of them in control, and the pacing of simulated time.
//!
//! - Control: the first client to send a request that changes anything
//!   (a command, a parameter set, a stream point, a capture set-up) holds
//!   control until it disconnects. Meanwhile the others may only read
//!   (`is_read_only`: info, status, parameters, their own telemetry,
//!   capture status and data); anything else is refused with
//!   `Error::ControlledByAnotherClient`, nothing applied. An idle client
//!   that only reads never locks anyone out.
//! - Each client has its own protocol `Server` (its own telemetry fields
//!   and rate; the controller's also holds the stream's last point).
//! - A disconnect is a lost link: a stream it was sending stops arriving,
//!   and the core's stream-loss stop acts in drive time as on a board.

use super::{is_read_only, Pace, SimDrive};
use anyhow::{Context, Result};
use servo_core::protocol::server::Server;
use servo_core::protocol::{self, DriveFrame, Error, Feed, FrameReader, Reply, Request, RequestFrame, FRAME_MAX};
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A stop flag for `serve` (tests stop their in-process drive with it).
pub type StopFlag = Arc<AtomicBool>;

/// One connected client.
struct Session {
    id: u64,
    peer: SocketAddr,
    rd: TcpStream,
    wr: std::io::BufWriter<TcpStream>,
    reader: FrameReader,
    server: Server,
    telemetry_next: u64,
    open: bool,
}

impl Session {
    fn send(&mut self, frame: &DriveFrame) {
        let mut buf = [0u8; FRAME_MAX];
        match protocol::encode(frame, &mut buf) {
            Some(bytes) => {
                if self.wr.write_all(bytes).is_err() {
                    self.open = false;
                }
            }
            None => eprintln!("drive: reply too large to encode: {frame:?}"),
        }
    }

    /// A telemetry frame to this client if its rate makes one due at
    /// period `k` (a position-loop boundary).
    fn telemetry(&mut self, drive: &SimDrive, k: u64) {
        let rate = self.server.telemetry_rate_hz();
        if rate == 0 || k < self.telemetry_next {
            return;
        }
        let every = (drive.pwm_hz() / f64::from(rate)).round().max(1.0) as u64;
        self.telemetry_next = k + every;
        let frame = self.server.telemetry_frame(&drive.cl.controller.telemetry());
        self.send(&DriveFrame::Telemetry(frame));
    }
}

/// The drive, its clients and the pacing state.
struct Serving {
    drive: SimDrive,
    sessions: Vec<Session>,
    next_id: u64,
    /// The client in control, by id.
    controller: Option<u64>,
    /// Wall-clock pacing: (wall instant, drive time) it started from.
    wall_anchor: Option<(Instant, f64)>,
    last_stream_frame: Instant,
}

impl Serving {
    /// One position-loop period of simulated time, with each client's
    /// telemetry.
    fn advance_period(&mut self) {
        self.drive.step_to_boundary(&mut Vec::new());
        let k = self.drive.cl.periods();
        for s in &mut self.sessions {
            s.telemetry(&self.drive, k);
        }
    }

    /// Exactly `periods` PWM periods (a stream frame's share in lock-step),
    /// ending on a position-loop boundary.
    fn advance_periods(&mut self, periods: u64) {
        let d = self.drive.divider();
        let target = self.drive.cl.periods() + periods;
        while self.drive.cl.periods() < target {
            self.drive.step();
            let k = self.drive.cl.periods();
            if k.is_multiple_of(d) {
                for s in &mut self.sessions {
                    s.telemetry(&self.drive, k);
                }
            }
        }
        if !self.drive.cl.periods().is_multiple_of(d) {
            self.advance_period();
        }
    }

    /// One request from client `i`: control checked, handled, answered.
    fn request(&mut self, i: usize, frame: RequestFrame) {
        let id = self.sessions[i].id;
        let fast = self.drive.options().pace == Pace::Fast;
        if !is_read_only(&frame.request) {
            match self.controller {
                Some(c) if c != id => {
                    let reply = DriveFrame::Reply { seq: frame.seq, reply: Reply::Error(Error::ControlledByAnotherClient) };
                    self.sessions[i].send(&reply);
                    return;
                }
                Some(_) => {}
                None => {
                    self.controller = Some(id);
                    eprintln!("drive: client {} has control", self.sessions[i].peer);
                }
            }
        }
        let is_stream = matches!(frame.request, Request::Stream(_));
        let live_before = self.drive.stream_live();
        let was_on = self.sessions[i].server.telemetry_rate_hz() > 0;
        let reply = self.drive.handle_with(&mut self.sessions[i].server, &frame);
        if !was_on && self.sessions[i].server.telemetry_rate_hz() > 0 {
            self.sessions[i].telemetry_next = self.drive.cl.periods();
        }
        if is_stream && fast && (self.drive.stream_live() || live_before) {
            // Lock-step: the frame was applied at a position-loop boundary
            // (the drive always rests on one); exactly one stream period
            // of simulated time follows, refused or not, so the drive's
            // clock keeps the stream's timeline.
            self.last_stream_frame = Instant::now();
            let periods = (self.drive.options().stream_period_s * self.drive.pwm_hz()).round().max(1.0) as u64;
            self.advance_periods(periods);
        }
        if let Some(reply) = reply {
            self.sessions[i].send(&reply);
        }
    }

    /// Reads what client `i` sent; false if nothing arrived.
    fn read(&mut self, i: usize, buf: &mut [u8]) -> bool {
        let n = match self.sessions[i].rd.read(buf) {
            Ok(0) => {
                self.sessions[i].open = false;
                return false;
            }
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted) => return false,
            Err(_) => {
                self.sessions[i].open = false;
                return false;
            }
        };
        for &b in &buf[..n] {
            let req = match self.sessions[i].reader.push(b) {
                Feed::Pending => continue,
                Feed::Dropped(e) => Err(e),
                Feed::Frame(f) => protocol::decode::<RequestFrame>(f),
            };
            match req {
                Err(e) => self.sessions[i].send(&SimDrive::frame_error(e)),
                Ok(frame) => self.request(i, frame),
            }
        }
        true
    }

    /// Drops closed clients; control and a live stream go with theirs.
    fn reap(&mut self) {
        let mut gone = Vec::new();
        self.sessions.retain(|s| {
            if !s.open {
                gone.push((s.id, s.peer));
            }
            s.open
        });
        for (id, peer) in gone {
            eprintln!("drive: client {peer} gone at t = {:.3} s", self.drive.cl.time_s());
            if self.controller == Some(id) {
                self.controller = None;
                // The link is lost: the stream stops arriving; the drive
                // runs on and the core's stream-loss stop acts.
                self.drive.set_stream_live(false);
            }
        }
    }

    /// Simulated time for this turn of the loop; true if the drive is
    /// idle-waiting on the wall clock.
    fn pace(&mut self) -> bool {
        let fast = self.drive.options().pace == Pace::Fast;
        if fast && self.drive.stream_live() && self.last_stream_frame.elapsed().as_secs_f64() > self.drive.options().stream_idle_s {
            // The stream has stopped arriving: the drive runs free again.
            self.drive.set_stream_live(false);
        }
        if fast && self.drive.stream_live() {
            self.wall_anchor = None;
            return true;
        }
        if fast && !self.sessions.is_empty() {
            self.wall_anchor = None;
            self.advance_period();
            return false;
        }
        // Realtime, or fast with nobody connected: the wall clock.
        let (wall0, sim0) = *self.wall_anchor.get_or_insert((Instant::now(), self.drive.cl.time_s()));
        let target = sim0 + wall0.elapsed().as_secs_f64();
        // Bounded catch-up, so a slow host still answers requests.
        let mut k = 0;
        while self.drive.cl.time_s() < target && k < 50 {
            self.advance_period();
            k += 1;
        }
        self.drive.cl.time_s() >= target
    }
}

/// Serves clients until `stop` is set.
pub fn serve(listener: TcpListener, opts: super::DriveOptions, stop: StopFlag) -> Result<()> {
    let drive = SimDrive::new(opts)?;
    eprintln!("drive: {}", drive.boot_note);
    listener.set_nonblocking(true)?;
    let mut s = Serving {
        drive,
        sessions: Vec::new(),
        next_id: 0,
        controller: None,
        wall_anchor: None,
        last_stream_frame: Instant::now(),
    };
    let mut buf = vec![0u8; 16 * 1024];
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((sock, peer)) => {
                eprintln!("drive: client {peer} connected");
                let session = (|| -> Result<Session> {
                    sock.set_nodelay(true)?;
                    sock.set_nonblocking(true)?;
                    let rd = sock.try_clone()?;
                    Ok(Session {
                        id: s.next_id,
                        peer,
                        rd,
                        wr: std::io::BufWriter::with_capacity(64 * 1024, sock),
                        reader: FrameReader::new(),
                        server: s.drive.new_server(),
                        telemetry_next: 0,
                        open: true,
                    })
                })();
                match session {
                    Ok(x) => {
                        s.next_id += 1;
                        s.sessions.push(x);
                    }
                    Err(e) => eprintln!("drive: client {peer}: {e:#}"),
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {}
            Err(e) => return Err(e).context("accept"),
        }
        let mut got = false;
        for i in 0..s.sessions.len() {
            got |= s.read(i, &mut buf);
        }
        let waiting = s.pace();
        for x in &mut s.sessions {
            if x.wr.flush().is_err() {
                x.open = false;
            }
        }
        s.reap();
        if !got && waiting {
            std::thread::sleep(Duration::from_micros(if s.sessions.is_empty() { 1000 } else { 200 }));
        }
    }
    Ok(())
}

/// Starts a drive on `127.0.0.1:0` in a thread (tests, benchmarks).
/// Returns the address, the stop flag and the thread.
pub fn spawn_local(opts: super::DriveOptions) -> Result<(SocketAddr, StopFlag, std::thread::JoinHandle<Result<()>>)> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    let addr = listener.local_addr()?;
    let stop: StopFlag = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let h = std::thread::spawn(move || serve(listener, opts, s));
    Ok((addr, stop, h))
}
