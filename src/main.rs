// Every evaluation of a diagnosis allocates whole-record columns; glibc's allocator returns
// them to the kernel and faults them back in (a third of a creep model's evaluation time).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    std::process::exit(optbench::cmd::main());
}
