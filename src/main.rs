//! The `farma` binary: everything lives in the library; see `farma --help`.

fn main() {
    std::process::exit(farma::cli::main());
}
