//! The weights topic over real iceoryx2: a predictor that subscribes after the trainer published
//! still gets the newest checkpoint, and is woken for it.

use std::time::Duration;

use mtanet_ipc::WeightsHeader;
use mtanet_ipc::node::{IpcConfig, create_node, remove_namespace_files};
use mtanet_ipc::weights_topic::{WeightsReceiver, WeightsSender};

#[test]
fn a_late_subscriber_gets_the_newest_weights() {
    let ipc = IpcConfig {
        namespace: format!("wt{}", std::process::id()),
    };
    {
        let trainer = create_node(&ipc, "trainer").unwrap();
        let sender = WeightsSender::open(&trainer).unwrap();
        for version in 1..=2u64 {
            publish(&sender, version, 0, &vec![version as u8; 1000]);
        }
        // The predictor starts now, after both publishes.
        let predictor = create_node(&ipc, "predictor").unwrap();
        let receiver = WeightsReceiver::open(&predictor).unwrap();
        sender.serve_new_subscribers().unwrap();
        let mut woken = false;
        receiver
            .listener()
            .timed_wait(|_| woken = true, Duration::from_secs(2))
            .unwrap();
        assert!(woken, "the late subscriber was not woken");
        let got = receiver
            .latest(|h, bytes| (h.version, bytes.len(), bytes[0]))
            .unwrap();
        assert_eq!(got, Some((2, 1000, 2)), "newest checkpoint, whole");
        // Nothing new: nothing pending, and no wake-up without a new subscriber.
        sender.serve_new_subscribers().unwrap();
        assert_eq!(receiver.latest(|h, _| h.version).unwrap(), None);
    }
    // iceoryx2 keeps a node counter per namespace by design; this namespace is used once.
    remove_namespace_files(&ipc.namespace);
}

/// Publishes `version` with `bytes`; `install_step` 0 is real time's "install on arrival".
fn publish(sender: &WeightsSender, version: u64, install_step: u64, bytes: &[u8]) {
    let header = WeightsHeader {
        version,
        install_step,
        ..Default::default()
    };
    sender.send(header, bytes).unwrap();
}

/// Lockstep learning drives each version from its own step: a predictor busy with one plan
/// while the trainer publishes several must still get every one, oldest first. In real time
/// only the newest of those pending is worth decoding.
#[test]
fn checkpoints_published_while_the_predictor_is_busy_all_arrive_in_order() {
    let ipc = IpcConfig {
        namespace: format!("wb{}", std::process::id()),
    };
    {
        let trainer = create_node(&ipc, "trainer").unwrap();
        let sender = WeightsSender::open(&trainer).unwrap();
        let predictor = create_node(&ipc, "predictor").unwrap();
        let receiver = WeightsReceiver::open(&predictor).unwrap();
        let n = 5;
        assert!(mtanet_ipc::weights_topic::SUBSCRIBER_BUFFER as u64 >= n);
        for version in 1..=n {
            publish(&sender, version, 100 * version, &vec![version as u8; 1000]);
        }
        let got = receiver
            .pending(|h, bytes| (h.version, bytes[999]))
            .unwrap();
        let want: Vec<(u64, u8)> = (1..=n).map(|v| (v, v as u8)).collect();
        assert_eq!(got, want, "every lockstep checkpoint, oldest first, whole");
        assert!(receiver.pending(|h, _| h.version).unwrap().is_empty());
        for version in n + 1..=n + 3 {
            publish(&sender, version, 0, &[0u8; 10]);
        }
        let got = receiver.pending(|h, _| h.version).unwrap();
        assert_eq!(got, [n + 3], "real time: the newest only");
        for version in [n + 4, n + 5] {
            publish(&sender, version, 0, &[0u8; 10]);
        }
        assert_eq!(receiver.latest(|h, _| h.version).unwrap(), Some(n + 5));
    }
    remove_namespace_files(&ipc.namespace);
}
