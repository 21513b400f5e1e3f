//! The `crom` binary: a thin shell over [`crom_pipeline::main_with_args`], started with bounded
//! malloc arenas ([`crom_pipeline::resources::bound_malloc_arenas`]) when it runs study stages
//! ([`crom_pipeline::runs_stages`]).

fn main() -> std::process::ExitCode {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if crom_pipeline::runs_stages(&args) {
        crom_pipeline::resources::bound_malloc_arenas();
    }
    std::process::ExitCode::from(crom_pipeline::main_with_args(args))
}
