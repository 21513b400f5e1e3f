//! The `crom` binary: a thin shell over [`crom_pipeline::main_with_args`].

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(crom_pipeline::main_with_args(std::env::args_os()))
}
