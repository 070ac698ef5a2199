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
            let header = WeightsHeader {
                version,
                ..Default::default()
            };
            sender.send(header, &vec![version as u8; 1000]).unwrap();
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

/// Lockstep learning drives each version from its own step: a predictor busy with one plan
/// while the trainer publishes several must still get every one, oldest first.
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
            let header = WeightsHeader {
                version,
                ..Default::default()
            };
            sender.send(header, &vec![version as u8; 1000]).unwrap();
        }
        let got = receiver.each(|h, bytes| (h.version, bytes[999])).unwrap();
        let want: Vec<(u64, u8)> = (1..=n).map(|v| (v, v as u8)).collect();
        assert_eq!(got, want, "every checkpoint, oldest first, whole");
        assert!(receiver.each(|h, _| h.version).unwrap().is_empty());
        // The newest of several, for a reader that wants only that.
        for version in [n + 1, n + 2] {
            let header = WeightsHeader {
                version,
                ..Default::default()
            };
            sender.send(header, &[0u8; 10]).unwrap();
        }
        assert_eq!(receiver.latest(|h, _| h.version).unwrap(), Some(n + 2));
    }
    remove_namespace_files(&ipc.namespace);
}
