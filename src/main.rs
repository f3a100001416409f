// Large allocations on huge pages (src/memory.rs).
#[global_allocator]
static ALLOCATOR: lightpath::memory::LargePages = lightpath::memory::LargePages;

fn main() {
    std::process::exit(lightpath::cli::main());
}
