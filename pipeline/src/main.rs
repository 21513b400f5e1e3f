//! The `crom` binary: a thin shell over [`crom_pipeline::main_with_args`], started with bounded
//! malloc arenas ([`crom_pipeline::resources::bound_malloc_arenas`]).

fn main() -> std::process::ExitCode {
    crom_pipeline::resources::bound_malloc_arenas();
    std::process::ExitCode::from(crom_pipeline::main_with_args(std::env::args_os()))
}
