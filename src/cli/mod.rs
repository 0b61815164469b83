//! The `stripmask` command: the parser and the dispatch to one module per subcommand. Each
//! subcommand's arguments resolve into the library's settings before it runs; the argument groups
//! several share are in [`args`].

/// `println!` for the commands' results, which does not panic when the reader has gone away
/// (`stripmask fly ... | head`): the command still finishes and writes its files.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// [`say!`] without the newline.
macro_rules! say_raw {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout().lock(), $($arg)*);
    }};
}

mod args;
mod build;
mod demo;
mod device;
mod fb;
mod fly;
mod info;
mod report;
mod serve;
mod stream_compare;
mod tradeoff;
mod view;

use clap::{Parser, Subcommand};
use stripmask::error::Result;

use build::BuildArgs;
use demo::DemoArgs;
use fb::FbArgs;
use fly::FlyArgs;
use info::InfoArgs;
use report::ReportArgs;
use serve::ServeArgs;
use stream_compare::StreamCompareArgs;
use tradeoff::TradeoffArgs;
use view::ViewArgs;

/// Adaptive streaming and CPU rendering of large terrains with strip masks.
#[derive(Parser, Debug)]
#[command(name = "stripmask", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Cut a DEM (PNG, GeoTIFF, .hgt, .asc, raw/BIL) into tiles and write a .smdb archive.
    Build(BuildArgs),
    /// Describe an archive (a file or an http:// URL).
    Info(InfoArgs),
    /// Serve one archive over HTTP with byte ranges (loopback by default).
    Serve(ServeArgs),
    /// Fly over an archive headless: stats.csv, PNG frames and a summary.
    Fly(FlyArgs),
    /// Fly over an archive in a window (WASD/arrows, Space/C, mouse drag; H HUD; Esc quits).
    View(ViewArgs),
    /// Fly over an archive on the Linux framebuffer (a scripted flight; Ctrl-C quits).
    Fb(FbArgs),
    /// Draw the flyover plots of DIR/stats.csv into DIR.
    Report(ReportArgs),
    /// The paper's PocketPC flyover over the Puget Sound model, in one command.
    Demo(DemoArgs),
    /// Measure every speed-for-accuracy knob: frame time against error, table, CSV and plot.
    Tradeoff(TradeoffArgs),
    /// Whole-tile belts against progressive tiles on the built-in flights over three links.
    StreamCompare(StreamCompareArgs),
}

/// Runs one command.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Build(a) => build::run(a),
        Command::Info(a) => info::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Fly(a) => fly::run(a),
        Command::View(a) => view::run(a),
        Command::Fb(a) => fb::run(a),
        Command::Report(a) => report::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Tradeoff(a) => tradeoff::run(a),
        Command::StreamCompare(a) => stream_compare::run(a),
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// clap's own checks of the definitions, among them that every default is a value the
    /// argument's parser accepts (the library's names and defaults included).
    #[test]
    fn the_parser_is_consistent_and_its_defaults_parse() {
        super::Cli::command().debug_assert();
    }
}
