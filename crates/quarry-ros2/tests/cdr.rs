//! CDR round trips, malformed input, type hashes, and the check against rosbags (Python).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use proptest::prelude::*;
use quarry_ros2::msgs::*;
use quarry_ros2::{Message, ros_msg};

ros_msg! {
    /// `std_msgs/msg/String`, whose Jazzy type hash is printed in rmw_zenoh's documentation.
    #[derive(Default)]
    pub struct StdString = "std_msgs/msg/String" {
        /// The text.
        pub data: String,
    }
}

#[test]
fn the_type_hash_of_std_msgs_string_is_ros_jazzys() {
    // the key expression in rmw_zenoh's README: 0/chatter/std_msgs::msg::dds_::String_/RIHS01_df66…
    assert_eq!(
        StdString::type_hash(),
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    );
    assert_eq!(
        quarry_ros2::rmw_zenoh::topic_key::<StdString>(0, "/chatter").unwrap(),
        "0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    );
}

fn scan(ranges: Vec<f32>, frame: &str, ns: i64) -> LaserScan {
    LaserScan {
        header: Header::new(Time::from_nanos(ns), frame),
        angle_min: -2.0,
        angle_max: 2.0,
        angle_increment: 0.01,
        time_increment: 1e-5,
        scan_time: 0.1,
        range_min: 0.05,
        range_max: 30.0,
        intensities: ranges.iter().map(|r| r * 0.5).collect(),
        ranges,
    }
}

fn tracks() -> TrackArray {
    TrackArray {
        header: Header::new(Time::from_nanos(1_234_567_890), "map"),
        tracks: (0..3)
            .map(|k| Track {
                id: k * 7 + 1,
                status: (k % 3) as u8,
                x: f64::from(k) * 0.3 - 1.0,
                y: 2.5,
                vx: 0.1,
                vy: -0.2,
                position_covariance: [0.01, 0.0, 0.0, 0.02],
                existence: 0.9,
            })
            .collect(),
    }
}

fn markers() -> MarkerArray {
    MarkerArray {
        markers: vec![
            Marker {
                action: Marker::DELETEALL,
                ..Marker::default()
            },
            Marker {
                header: Header::new(Time::from_nanos(5), "map"),
                ns: "tracks".into(),
                id: 3,
                r#type: Marker::CYLINDER,
                pose: Pose::planar(1.0, 2.0, 0.3),
                scale: Vector3 {
                    x: 0.4,
                    y: 0.4,
                    z: 1.7,
                },
                color: ColorRGBA {
                    r: 1.0,
                    g: 0.5,
                    b: 0.0,
                    a: 0.8,
                },
                text: "3".into(),
                points: vec![Point {
                    x: 1.0,
                    y: 2.0,
                    z: 0.0,
                }],
                ..Marker::default()
            },
        ],
    }
}

fn detections() -> Detection2DArray {
    let h = Header::new(Time::from_nanos(40_000_000), "camera");
    Detection2DArray {
        header: h.clone(),
        detections: vec![Detection2D {
            header: h,
            results: vec![ObjectHypothesisWithPose {
                hypothesis: ObjectHypothesis {
                    class_id: "person".into(),
                    score: 1.0,
                },
                pose: PoseWithCovariance::default(),
            }],
            bbox: BoundingBox2D {
                center: Pose2D {
                    position: Point2D { x: 100.5, y: 200.0 },
                    theta: 0.0,
                },
                size_x: 32.0,
                size_y: 84.0,
            },
            id: "17".into(),
        }],
    }
}

fn tf() -> TFMessage {
    TFMessage {
        transforms: vec![TransformStamped::planar(
            Time::from_nanos(9),
            "map",
            "laser",
            0.5,
            -0.25,
            1.0,
        )],
    }
}

fn pose_stamped() -> PoseStamped {
    PoseStamped {
        header: Header::new(Time::from_nanos(77), "map"),
        pose: Pose::planar(3.0, 4.0, -0.5),
    }
}

fn images() -> (CompressedImage, Image) {
    let h = Header::new(Time::from_nanos(1), "camera");
    (
        CompressedImage {
            header: h.clone(),
            format: "png".into(),
            data: vec![137, 80, 78, 71, 1, 2, 3],
        },
        Image {
            header: h,
            height: 2,
            width: 3,
            encoding: "mono8".into(),
            is_bigendian: 0,
            step: 3,
            data: vec![1, 2, 3, 4, 5, 6],
        },
    )
}

fn pose_array() -> PoseArray {
    PoseArray {
        header: Header::new(Time::from_nanos(3), "map"),
        poses: vec![Pose::planar(1.0, 1.0, 0.0), Pose::planar(-1.0, 2.0, 1.0)],
    }
}

/// Every sample as (type name, definition, hash, bytes).
fn samples() -> Vec<(&'static str, String, String, Vec<u8>)> {
    fn one<M: Message>(m: &M) -> (&'static str, String, String, Vec<u8>) {
        (M::NAME, M::definition(), M::type_hash(), m.to_cdr())
    }
    let (ci, im) = images();
    vec![
        one(&scan(
            vec![1.0, 2.5, f32::INFINITY, 0.25],
            "laser",
            1_500_000_001,
        )),
        one(&tracks()),
        one(&markers()),
        one(&detections()),
        one(&tf()),
        one(&pose_stamped()),
        one(&pose_array()),
        one(&TwistStamped::planar(
            Time::from_nanos(11),
            "base_link",
            0.3,
            -0.1,
        )),
        one(&ci),
        one(&im),
        one(&StdString { data: "odd".into() }),
    ]
}

fn roundtrip<M: Message + PartialEq + std::fmt::Debug>(m: &M) {
    let b = m.to_cdr();
    assert_eq!(&M::from_cdr(&b).unwrap(), m);
    // every strict prefix is an error (or, for a prefix ending in padding, the same message)
    for n in 0..b.len() {
        if let Ok(p) = M::from_cdr(&b[..n]) {
            assert_eq!(
                &p,
                m,
                "prefix {n} of {} decoded to another message",
                M::NAME
            );
        }
    }
}

#[test]
fn every_sample_round_trips_and_its_prefixes_fail_cleanly() {
    roundtrip(&scan(vec![1.0, 2.0], "l", 5));
    roundtrip(&tracks());
    roundtrip(&markers());
    roundtrip(&detections());
    roundtrip(&tf());
    roundtrip(&pose_stamped());
    roundtrip(&pose_array());
    let (ci, im) = images();
    roundtrip(&ci);
    roundtrip(&im);
}

#[test]
fn definitions_list_nested_types_once_with_the_mcap_separator() {
    let d = MarkerArray::definition();
    assert!(d.starts_with("visualization_msgs/Marker[] markers\n"));
    assert_eq!(d.matches("MSG: std_msgs/Header\n").count(), 1);
    assert!(d.contains(&format!("{}\nMSG: geometry_msgs/Pose\n", "=".repeat(80))));
    assert!(Marker::definition().contains("int32 type\n"));
}

proptest! {
    #[test]
    fn scans_round_trip(ranges in proptest::collection::vec(any::<f32>(), 0..50),
                        frame in "[a-z_/]{0,12}", ns in any::<i64>()) {
        let s = scan(ranges, &frame, ns);
        let b = s.to_cdr();
        let back = LaserScan::from_cdr(&b).unwrap();
        // bit equality (NaN-safe)
        prop_assert_eq!(back.to_cdr(), b);
        prop_assert_eq!(back.header.frame_id, frame);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let _ = LaserScan::from_cdr(&bytes);
        let _ = MarkerArray::from_cdr(&bytes);
        let _ = TrackArray::from_cdr(&bytes);
        let _ = Detection2DArray::from_cdr(&bytes);
        let _ = TFMessage::from_cdr(&bytes);
    }

    #[test]
    fn times_convert_both_ways(ns in -(i64::from(i32::MAX) * 1_000_000_000)..(i64::from(i32::MAX) * 1_000_000_000)) {
        let t = Time::from_nanos(ns);
        prop_assert!(t.nanosec < 1_000_000_000);
        prop_assert_eq!(t.nanos(), ns);
    }
}

#[test]
fn rosbags_reads_and_writes_the_same_bytes_and_hashes() {
    let reqs = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/requirements.txt");
    let Some(py) =
        quarry_testkit::python::venv_or_skip(Path::new(env!("CARGO_TARGET_TMPDIR")), "ros2", &reqs)
    else {
        return;
    };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ros2-cdr-samples");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let all = samples();
    for (name, def, hash, bytes) in &all {
        let stem = name.replace('/', "__");
        std::fs::write(dir.join(format!("{stem}.cdr")), bytes).unwrap();
        std::fs::write(dir.join(format!("{stem}.msg")), def).unwrap();
        std::fs::write(dir.join(format!("{stem}.hash")), hash).unwrap();
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_cdr.py");
    let out = py.command().arg(&script).arg(&dir).output().unwrap();
    assert!(
        out.status.success(),
        "check_cdr.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let recs = v.as_array().unwrap();
    assert_eq!(recs.len(), all.len());
    for r in recs {
        let ty = r["type"].as_str().unwrap();
        assert_eq!(
            r["hash_quarry"], r["hash_rosbags"],
            "{ty}: type hash differs"
        );
        assert_eq!(
            r["bytes_equal"], true,
            "{ty}: rosbags re-serialises other bytes"
        );
        match ty {
            "sensor_msgs/msg/LaserScan" => {
                assert_eq!(r["frame_id"], "laser");
                assert_eq!(r["stamp"], serde_json::json!([1, 500_000_001]));
                let rg: Vec<f64> = r["ranges"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap_or(f64::INFINITY))
                    .collect();
                assert_eq!(rg[..2], [1.0, 2.5]);
            }
            "quarry_msgs/msg/TrackArray" => {
                assert_eq!(r["tracks"][2][0], 15);
                assert_eq!(r["tracks"][1][1], -0.7);
            }
            "vision_msgs/msg/Detection2DArray" => assert_eq!(r["ids"][0], "17"),
            _ => {}
        }
    }
    // the standard types were checked against Jazzy's own definitions, not ours
    let standard = recs.iter().filter(|r| r["standard"] == true).count();
    assert_eq!(
        standard,
        all.len() - 2,
        "vision_msgs and quarry_msgs are the only non-Jazzy-store types here"
    );
}
