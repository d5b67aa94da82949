fn main() {
    std::process::exit(optbench::cli::main());
}
