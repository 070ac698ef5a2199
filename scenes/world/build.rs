fn main() {
    mtanet_rpath::emit();
}
