//! One module per subcommand of the `heml` binary.

/// `println!` for the subcommands' reports, through [`out::write`]: a closed pipe
/// (`heml bench | head -1`) ends the command quietly instead of panicking.
macro_rules! outln {
    () => { $crate::cli::out::write(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::cli::out::write(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `print!` through [`out::write`] (see [`outln!`]).
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::out::write(format_args!($($arg)*)) };
}

pub mod bench;
pub mod bench_energy;
pub mod bench_implicit;
pub mod bench_nodal;
pub mod bench_tangent;
pub mod demo;
pub mod device_tuning;
pub mod haptic;
pub mod info;
pub mod materials;
pub mod out;
pub mod run;
pub mod validate;
pub mod view;
