fn main() {
    std::process::exit(lightpath::cli::main());
}
