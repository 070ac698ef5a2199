//! System tests live in `tests/`; the process helpers they use are `mtanet_mta::stack`.
