//! The host tool (`host-sim drive …`): talks the drive protocol to a board
//! over a serial port or to the simulated drive over TCP, with the same
//! commands either way. docs/host-tool.md lists them.

pub mod access;
pub mod analysis;
pub mod bench;
pub mod bench_asap;
pub mod bench_family;
pub mod bench_gain;
pub mod cli;
pub mod client;
pub mod config_file;
pub mod moves;
pub mod observer;
pub mod params;
pub mod run;
pub mod scope;
pub mod stream;
pub mod stream_cmd;
pub mod stiffness;
pub mod stream_loss;
pub mod test;
pub mod view;
pub mod watch_bench;

pub use access::{command, fetch_params, info_json, param_get, param_index, param_list, param_set, param_set_value, reply_text};
pub use cli::{ConnectArgs, DriveArgs, DriveCmd, IdentifyCmd, ObserverCmd, ParamCmd};
pub use run::run_cli;
pub use scope::{capture, capture_with, signal_by_name, signal_name, CaptureData, SIGNAL_NAMES};
