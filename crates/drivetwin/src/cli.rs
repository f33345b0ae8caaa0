//! The command line.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// `drivetwin --version`: the version and the device files built into the binary
/// (`devices/*.toml`), so that a report names what the binary simulates; `-V` is the version.
fn long_version() -> &'static str {
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| {
        let width = devices::ALL.iter().map(|d| d.name.len()).max().unwrap_or(0);
        let mut text = format!(
            "{}\ndevice files (devices/*.toml, built in):",
            env!("CARGO_PKG_VERSION")
        );
        for d in devices::ALL {
            text.push_str(&format!(
                "\n  {:<width$} {} ({}), {} objects",
                d.name,
                d.product_name,
                d.vendor_name,
                d.objects.len()
            ));
        }
        text
    })
}

#[derive(Parser, Debug)]
#[command(
    name = "drivetwin",
    version,
    long_version = long_version(),
    about = "Software twins of fieldbus motor controllers, and a CANopen master",
    after_help = "Exit codes: 0 ok, 1 failure, 2 usage, 3 bus connection, 4 timeout, 5 SDO abort or refused, 6 protocol error, 7 drive fault."
)]
pub struct Cli {
    /// Log more (or set DRIVETWIN_LOG, e.g. DRIVETWIN_LOG=debug).
    #[arg(short, long, global = true)]
    pub verbose: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Start a cell: drives on a virtual CAN bus served over socketcand.
    Run(Box<RunArgs>),
    /// Print the CiA 306 EDS of a personality.
    Eds {
        #[arg(long, default_value = "cmmp-as")]
        device: String,
        /// Write to a file instead of standard output.
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
    /// Print the EtherCAT slave information (ESI, ETG.2000) XML of a personality.
    Esi {
        #[arg(long, default_value = "cmmp-as")]
        device: String,
        /// The generic CiA 402 drive of this EDS / DCF on EtherCAT instead of `--device`.
        #[arg(long)]
        eds: Option<PathBuf>,
        /// Write to a file instead of standard output.
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
    /// List the personalities this build knows.
    Devices,
    /// SDO read or write on a node.
    #[command(subcommand)]
    Sdo(SdoCommand),
    /// Send an NMT node-control command.
    Nmt {
        #[arg(value_enum)]
        command: NmtArg,
        /// Node-ID, 0 = all nodes.
        #[arg(default_value_t = 0)]
        node: u8,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Show or change a node's PDO configuration (CiA 301 procedure).
    #[command(subcommand)]
    Pdo(PdoCommand),
    /// Produce SYNC messages.
    Sync {
        /// Period in milliseconds.
        #[arg(long, default_value_t = 10.0)]
        period_ms: f64,
        /// Stop after this many SYNCs (default: until Ctrl-C).
        #[arg(long)]
        count: Option<u64>,
        /// Carry a counter byte 1…N (CiA 301 1019h); 0 = no counter.
        #[arg(long, default_value_t = 0)]
        counter: u8,
        #[arg(long, default_value = "080")]
        cob_id: String,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Layer setting services (CiA 305): find unconfigured nodes and give them a node-ID.
    #[command(subcommand)]
    Lss(LssCommand),
    /// Kinco FD / CD drives over their RS232 telegrams (a serial port or a twin's pty link):
    /// read, write, status.
    Kinco(drivetwin::vendors::kinco::rs232_commands::KincoArgs),
    /// CiA 402 drive commands over SDO: state, enable, disable, move, velocity, torque.
    Drive {
        node: u8,
        #[command(subcommand)]
        command: DriveCommand,
        /// Wait until the target is reached (move, velocity, torque).
        #[arg(long, global = true)]
        wait: bool,
        /// Timeout of each state change and of --wait, ms.
        #[arg(long, global = true, default_value_t = 5000)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Which nodes answer (SDO read of 1000h on every node-ID).
    Scan {
        #[arg(long, default_value_t = 300)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// A minimal EtherCAT master to check a chain: scan, AL states, CoE SDO.
    #[command(subcommand)]
    Ecat(EcatCommand),
    /// FHPP master commands to a CMMO-ST over Modbus TCP: status, enable, home, move, records, PNUs.
    Fhpp(drivetwin::vendors::festo_cmmo_st::fhpp_commands::FhppArgs),
    /// Print every frame on the bus, decoded.
    Monitor {
        /// Stop after this many frames.
        #[arg(long)]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long)]
        seconds: Option<f64>,
        /// The bus's bit rate: print the bus load of every 500 ms window from the start (the
        /// frames seen, each for its exact bit time; quiet windows in a row as one line), as
        /// the cell measures it.
        #[arg(long)]
        bitrate: Option<u32>,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Run a script of requests (SDO, NMT and PDO steps in a TOML file, or a candump log)
    /// against a node and write every request and answer with its time: a recording.
    Record(RecordArgs),
    /// Replay a recording's requests against a node and report each answer that differs:
    /// exit code 0 when every answer is equal, 1 when any differs, 2 on a usage or I/O error.
    Diff(DiffArgs),
    /// Run a scenario file (a cell and a timeline of actions and expectations) on the
    /// virtual clock: prints the report; exit code 0 when every expectation is met, 1 if not.
    Scenario(ScenarioArgs),
    /// Write a cell as an FMI 3.0 co-simulation FMU: the importer's doStep advances the
    /// cell's virtual clock; per drive, load torque and digital inputs in, shaft, current and
    /// statusword out (docs/cosimulation.md).
    Fmu(FmuArgs),
    /// Write the IO-Link device descriptions (IODD 1.1) of a personality: for the CMMO-ST the
    /// two files its manual names (FHPP 8 bytes, FHPP + FPC 16 bytes).
    Iodd(drivetwin::vendors::festo_cmmo_st::iodd_command::IoddArgs),
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    /// The script: a TOML file (`*.toml`) of steps, or a candump log whose master frames are
    /// the requests.
    pub script: PathBuf,
    /// Write the recording to this file (default: standard output).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// In a candump log, how long an SDO request waits for its answer, ms.
    #[arg(long, default_value_t = 1000)]
    pub sdo_timeout_ms: u64,
    /// In a candump log, how long the answers to the last request are gathered, ms.
    #[arg(long, default_value_t = 200)]
    pub quiet_ms: u64,
    #[command(flatten)]
    pub bus: BusArgs,
}

#[derive(Args, Debug)]
pub struct DiffArgs {
    /// The recording whose requests are replayed (`drivetwin record`'s output).
    pub recording: PathBuf,
    /// How far apart an answer's delays after its request may be, ms.
    #[arg(long, default_value_t = 50.0)]
    pub time_tolerance: f64,
    /// Compare with this recording instead of replaying on a bus.
    #[arg(long)]
    pub with: Option<PathBuf>,
    /// Write the replay as a recording to this file.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub bus: BusArgs,
}

#[derive(Args, Debug)]
pub struct ScenarioArgs {
    /// The scenario files (TOML), run one after another, each on a cell of its own.
    #[arg(value_name = "FILE", required = true, num_args = 1..)]
    pub files: Vec<PathBuf>,
    /// Write every frame of the run to this file (pcap; `*.log`: candump), stamped with the
    /// virtual clock; with one scenario file only.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Print the report as JSON (with several files: an array of reports, in their order).
    #[arg(long)]
    pub json: bool,
    /// Write every drive's shaft, current and statusword to this CSV file, sampled on the
    /// virtual clock every --sample-ms (from 0).
    #[arg(long)]
    pub samples: Option<PathBuf>,
    /// The sampling period of --samples, ms.
    #[arg(long, default_value_t = 1.0, requires = "samples")]
    pub sample_ms: f64,
}

#[derive(Args, Debug)]
pub struct FmuArgs {
    /// The cell file (packed into the FMU's resources/).
    #[arg(long)]
    pub config: PathBuf,
    /// A scenario file whose actions run inside the FMU at their times (NMT start, modes,
    /// enabling): the cell's start; its cell and its expectations are not used.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// The FMU to write.
    #[arg(long, short)]
    pub output: PathBuf,
    /// The FMU's binary, `libdrivetwin_cell.so` of crates/cell-fmu (`scripts/cell-fmu`
    /// builds it); default: next to this drivetwin binary.
    #[arg(long)]
    pub library: Option<PathBuf>,
    /// The network interface of the chain of the EtherCAT slaves that name none, as
    /// `drivetwin run --ethercat` takes it: the drives whose `interfaces` list "ethercat"
    /// without `ethercat = "IFNAME"`; when no drive lists interfaces, every drive. Kept in the
    /// FMU; its raw socket opens when the importer instantiates it.
    #[arg(long, value_name = "IFNAME")]
    pub ethercat: Option<String>,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Personality of the single drive (ignored with --config).
    #[arg(long, default_value = "cmmp-as")]
    pub device: String,
    /// Node-ID of the single drive (ignored with --config); default 1, or a DCF's
    /// `[DeviceComissioning] NodeID` with --eds.
    #[arg(long)]
    pub node: Option<u8>,
    /// The single drive is a CiA 402 drive from this EDS or DCF (CiA 306) instead of a
    /// built-in --device: its dictionary, modes and homing methods, the default servo motor.
    #[arg(long, value_name = "FILE", conflicts_with = "config")]
    pub eds: Option<PathBuf>,
    /// socketcand server address.
    #[arg(long)]
    pub socketcand: Option<String>,
    /// Bus name socketcand clients open.
    #[arg(long)]
    pub channel: Option<String>,
    /// The bit rate of every CAN bus, bit/s, or `instant` (frames cross at once: fast tests,
    /// latency benchmarks). Default: a bus's `bitrate` in the cell file, else the rate its
    /// nodes' switches and objects set (the CMMP-AS's DIP6/DIP7: 125 kbit/s untouched).
    #[arg(long, value_name = "BIT/S|instant")]
    pub bitrate: Option<drivetwin::cell::bus_rate::BitrateSetting>,
    /// Bridge this SocketCAN interface (e.g. vcan0, can0) onto the bus.
    #[arg(long)]
    pub socketcan: Option<String>,
    /// Join the socketcand server at ADDR as a client: the cell's (first) bus is that
    /// server's bus, so several twin processes make one plant.
    #[arg(long, value_name = "ADDR")]
    pub socketcand_join: Option<String>,
    /// Where stored parameter sets live (one file per node; the CMMO-ST's permanent memory,
    /// PNU 127, as its parameter file). Without it, 1010h "save" and PNU 127:2 are accepted
    /// but nothing survives the process.
    #[arg(long)]
    pub state_dir: Option<PathBuf>,
    /// A cell file with several drives (TOML). Given several times, each cell runs on a loop
    /// and a thread of its own, in one process; the other options apply to the first cell.
    #[arg(long)]
    pub config: Vec<PathBuf>,
    /// Write every bus frame to FILE: pcap (LINKTYPE_CAN_SOCKETCAN), or candump if FILE ends
    /// in .log; with --ethercat, a pcap of the Ethernet frames in and out.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Run on the virtual clock for this many seconds, as fast as possible, deterministically
    /// (no socketcand server; frames come from --inject).
    #[arg(long, value_name = "SECONDS")]
    pub virtual_seconds: Option<f64>,
    /// candump .log of frames to feed a virtual-clock run at their timestamps.
    #[arg(long, requires = "virtual_seconds")]
    pub inject: Option<PathBuf>,
    /// Modbus TCP server address of a CMMO-ST (`--device cmmo-st`; default 127.0.0.1:1502).
    #[arg(long, value_name = "ADDR")]
    pub modbus: Option<String>,
    /// CMMO-ST Modbus connection watchdog, ms: 0 = off (factory setting), 1…99 act as 100,
    /// at most 5000.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub modbus_timeout_ms: u16,
    /// How a CMMO-ST's Modbus connection is served: `cell` by the cell's loop, with the other
    /// drives and sockets of the cell on one clock (default); `thread` by a thread of its own
    /// that reads it between cycles, as the controller's fieldbus task; `async` as a tokio task
    /// on a thread of its own.
    #[arg(long, value_enum, value_name = "IO", default_value_t = ModbusIo::Cell)]
    pub modbus_io: ModbusIo,
    /// The network interface of the cell's EtherCAT chain (raw Ethernet, needs
    /// CAP_NET_RAW): the drives whose `interfaces` list "ethercat" without naming a chain;
    /// when no drive lists interfaces, every drive, as a chain of slaves in cell-file order
    /// instead of CAN. `--trace F.pcap` records every frame in and out (Ethernet pcap).
    #[arg(long, value_name = "IFNAME", conflicts_with_all = ["virtual_seconds"])]
    pub ethercat: Option<String>,
    /// Run the cell loop's thread at SCHED_FIFO with this priority (1…99; root, CAP_SYS_NICE
    /// or RLIMIT_RTPRIO), as a drive's firmware runs its fieldbus task: a frame is answered
    /// before any normal-priority process runs. Refused, the run stops with the reason.
    #[arg(long, value_name = "PRIO", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub rt_priority: Option<u8>,
    /// Give the cell loop's thread a time slice of this many µs (100…100000) under the fair
    /// scheduler (EEVDF, Linux 6.12+; no privilege): woken by a frame, it runs before
    /// neighbours on the default slice. Refused or not kept, the run stops with the reason.
    #[arg(long, value_name = "US", conflicts_with = "rt_priority",
          value_parser = clap::value_parser!(u32).range(100..=100_000))]
    pub sched_slice_us: Option<u32>,
    /// The cell loop spins on its sockets (EtherCAT, Modbus TCP) instead of sleeping, as the device's fieldbus hardware is always awake:
    /// the lowest round trip, at the price of one CPU kept busy.
    #[arg(long)]
    pub busy_poll: bool,
    /// Serve the (first) drive's CI terminal, the CMMP-AS debug console with its SDO
    /// simulation (`?606100` → `=606100:01`), on this loopback TCP address.
    #[arg(long, value_name = "ADDR", conflicts_with_all = ["virtual_seconds"])]
    pub ci_terminal: Option<String>,
    /// The (first) drive's RS232 port (a Kinco's 10-byte telegrams): PATH becomes a link to a
    /// pty of the twin that pyserial opens as a serial port; a real device (/dev/ttyUSB0)
    /// is opened instead.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["virtual_seconds"])]
    pub rs232: Option<PathBuf>,
    /// The (first) drive's RS485 port (a Kinco FD3's Modbus RTU), as --rs232.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["virtual_seconds"])]
    pub rs485: Option<PathBuf>,
    /// The web console's address (`off`: none). Default 127.0.0.1:8080 when that port is free;
    /// beyond loopback every write needs the token printed at start. Served with the cell
    /// loop (not with --virtual-seconds).
    #[arg(long, value_name = "ADDR|off", conflicts_with_all = ["virtual_seconds"])]
    pub http: Option<String>,
}

/// `--modbus-io`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModbusIo {
    Cell,
    Thread,
    Async,
}

#[derive(Args, Debug, Clone)]
pub struct BusArgs {
    /// socketcand server to join.
    #[arg(long, global = true, default_value = "127.0.0.1:29536")]
    pub socketcand: String,
    /// Bus name to open on the socketcand server.
    #[arg(long, global = true, default_value = "vcan0")]
    pub channel: String,
    /// Use this SocketCAN interface instead of socketcand.
    #[arg(long, global = true)]
    pub can: Option<String>,
    /// Print JSON instead of text.
    #[arg(long, global = true)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
pub enum SdoCommand {
    /// Read (upload) an entry.
    Read {
        node: u8,
        /// Index, hex (0x1018 or 1018).
        index: String,
        /// Sub-index, hex.
        #[arg(default_value = "0")]
        sub: String,
        #[command(flatten)]
        typing: TypeArgs,
        #[arg(long, default_value_t = 1000)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Write (download) an entry.
    Write {
        node: u8,
        index: String,
        sub: String,
        value: String,
        #[command(flatten)]
        typing: TypeArgs,
        #[arg(long, default_value_t = 1000)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
}

/// How an SDO value is typed: named, or taken from a personality's dictionary.
#[derive(Args, Debug, Clone)]
pub struct TypeArgs {
    /// Type to decode or encode as: u8 u16 u32 u64 i8 i16 i32 i64 f32 f64 bool str hex.
    #[arg(long = "type", short = 't')]
    pub data_type: Option<String>,
    /// Take the type from this personality's dictionary.
    #[arg(long)]
    pub device: Option<String>,
}

#[derive(Subcommand, Debug)]
pub enum PdoCommand {
    /// Print every RPDO and TPDO of a node.
    Show {
        node: u8,
        #[arg(long, default_value_t = 1000)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Configure one PDO: `drivetwin pdo map 1 tpdo1 --cob-id 181 --type 255 --map 6041:00:16`.
    Map {
        node: u8,
        /// rpdoN or tpdoN.
        pdo: String,
        /// COB-ID, hex (default: the pre-defined connection set for the node).
        #[arg(long)]
        cob_id: Option<String>,
        /// Transmission type 0…240, 254, 255.
        #[arg(long = "type", default_value_t = 255)]
        transmission_type: u8,
        /// Inhibit time in 100 µs (TPDOs).
        #[arg(long)]
        inhibit: Option<u16>,
        /// Event timer in ms.
        #[arg(long)]
        event_timer: Option<u16>,
        /// Mapped objects INDEX:SUB:BITS, hex index and sub-index, in order.
        #[arg(long = "map", value_delimiter = ',')]
        map: Vec<String>,
        /// Leave the PDO disabled.
        #[arg(long)]
        disabled: bool,
        #[arg(long, default_value_t = 1000)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
}

#[derive(Subcommand, Debug)]
pub enum DriveCommand {
    /// Print the state and the actual values.
    State,
    /// Fault reset if needed, then to OPERATION ENABLED.
    Enable,
    /// Shutdown: READY TO SWITCH ON, output stage off.
    Disable,
    /// Profile position move to TARGET (position units).
    Move {
        #[arg(allow_hyphen_values = true)]
        target: i32,
        #[arg(long)]
        relative: bool,
        /// Profile velocity 6081h.
        #[arg(long)]
        velocity: Option<u32>,
        /// Profile acceleration 6083h.
        #[arg(long)]
        accel: Option<u32>,
        /// Profile deceleration 6084h.
        #[arg(long)]
        decel: Option<u32>,
    },
    /// Profile velocity mode at VELOCITY (speed units); velocity mode VL (6042h, s16) on a
    /// drive without PV.
    Velocity {
        #[arg(allow_hyphen_values = true)]
        velocity: i32,
    },
    /// Profile torque mode at TORQUE (‰ of the rated torque).
    Torque {
        #[arg(allow_hyphen_values = true)]
        torque: i16,
        /// Torque slope 6087h, ‰/s (refused on a drive without 6087h).
        #[arg(long)]
        slope: Option<u32>,
    },
}

#[derive(Subcommand, Debug)]
pub enum LssCommand {
    /// Fastscan for an unconfigured node; with --node, give it that node-ID and store it.
    Fastscan {
        #[arg(long)]
        node: Option<u8>,
        /// Per-step answer timeout.
        #[arg(long, default_value_t = 30)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
    /// Switch every node to configuration, set the node-ID of the one node on the bus, store.
    SetNode {
        node: u8,
        #[arg(long, default_value_t = 200)]
        timeout_ms: u64,
        #[command(flatten)]
        bus: BusArgs,
    },
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum NmtArg {
    Start,
    Stop,
    PreOperational,
    ResetNode,
    ResetCommunication,
}

/// Where the EtherCAT chain is and how to print.
#[derive(Args, Debug, Clone)]
pub struct EcatLinkArgs {
    /// Network interface the chain hangs on (raw Ethernet; needs CAP_NET_RAW).
    #[arg(long, short = 'i')]
    pub interface: String,
    /// How long to wait for one frame to come back, ms (sent 3 times in all).
    #[arg(long, default_value_t = 50)]
    pub frame_timeout_ms: u64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
pub enum EcatCommand {
    /// Count the slaves, give them station addresses (0x1000 + n) and print their SII
    /// identity, name, AL state and the links of ports 0 and 1 (DL status 0x0110: where the
    /// line is cut).
    Scan {
        #[command(flatten)]
        link: EcatLinkArgs,
    },
    /// Print the AL state of the slaves, or request STATE (one AL control write, as SOEM's
    /// write_state: Init -> Op is refused, not walked) and wait for it.
    State {
        #[arg(value_enum)]
        state: Option<EcatStateArg>,
        /// Slave number (1 = first on the line); default: every slave, in line order.
        #[arg(long)]
        slave: Option<u16>,
        /// How long to wait for the requested state, ms.
        #[arg(long, default_value_t = 5000)]
        timeout_ms: u64,
        /// SDO timeout while reading the PDO assignment for Safe-Op, ms.
        #[arg(long, default_value_t = 1000)]
        sdo_timeout_ms: u64,
        #[command(flatten)]
        link: EcatLinkArgs,
    },
    /// CoE SDO read or write through a slave's mailbox (a slave in Init is put in Pre-Op).
    #[command(subcommand)]
    Sdo(EcatSdoCommand),
}

#[derive(Subcommand, Debug)]
pub enum EcatSdoCommand {
    /// Read (upload) an entry: `drivetwin ecat sdo read -i eth1 --slave 1 0x1018:1`.
    Read {
        /// INDEX:SUB, hex (0x1018:01, 1018:1; INDEX alone means sub-index 0).
        object: String,
        #[command(flatten)]
        target: EcatSdoTarget,
    },
    /// Write (download) an entry: `drivetwin ecat sdo write -i eth1 0x6065:0 12345 --type u32`.
    Write {
        /// INDEX:SUB, hex.
        object: String,
        /// The value: a number (decimal or 0x hex), text for `str`, hex bytes for `hex`.
        #[arg(allow_hyphen_values = true)]
        value: String,
        #[command(flatten)]
        target: EcatSdoTarget,
    },
}

/// Which slave an EtherCAT SDO command talks to, and how.
#[derive(Args, Debug, Clone)]
pub struct EcatSdoTarget {
    /// Slave number (1 = first on the line).
    #[arg(long, default_value_t = 1)]
    pub slave: u16,
    #[command(flatten)]
    pub typing: TypeArgs,
    /// SDO response timeout, ms.
    #[arg(long, default_value_t = 1000)]
    pub timeout_ms: u64,
    #[command(flatten)]
    pub link: EcatLinkArgs,
}

/// AL states a master requests (no Bootstrap: the CMMP-AS has none).
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum EcatStateArg {
    Init,
    Preop,
    Safeop,
    Op,
}
