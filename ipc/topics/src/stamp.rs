//! One clock for every process: `CLOCK_MONOTONIC` is shared across processes on a host, unlike
//! `std::time::Instant`, whose value cannot be sent. Messages carry it for latency measurement.

/// Nanoseconds of `CLOCK_MONOTONIC`.
pub fn monotonic_ns() -> u64 {
    let ts = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Nanoseconds elapsed since `stamp_ns` (0 if the stamp lies in the future).
pub fn elapsed_ns(stamp_ns: u64) -> u64 {
    monotonic_ns().saturating_sub(stamp_ns)
}

#[cfg(test)]
mod tests {
    #[test]
    fn monotonic_clock_advances() {
        let a = super::monotonic_ns();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = super::monotonic_ns();
        assert!(
            b >= a + 1_000_000,
            "clock moved {} ns over a 2 ms sleep",
            b - a
        );
    }
}
