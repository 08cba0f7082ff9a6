//! The `assetfield` command-line tool. See `assetfield --help`.

fn main() {
    std::process::exit(assetfield_cli::main_with_args(std::env::args_os()));
}
