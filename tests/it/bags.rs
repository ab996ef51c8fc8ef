//! ROS 2 bags: `kitti2pgm unpack` and the bag reader on `fixtures/own_lidar_bag` (real VLP-16
//! and Pandar40P scans written by rosbags, an independent official writer; one message
//! big-endian), and on bad bags made here.

use std::path::{Path, PathBuf};

use kitti2pgm::source::bag::Bag;
use kitti2pgm::source::pcd;
use kitti2pgm::source::pointcloud2::PointCloud2;

use super::util::{fixture, run_text, s, tmp};
use serde_json::json;

fn bag() -> PathBuf {
    fixture("own_lidar_bag")
}

fn vlp16() -> PathBuf {
    fixture("lidars/velodyne/vlp16_1673400472138016708.pcd")
}

/// The stream of a bag's point cloud topic `name`.
fn messages_of(bag: &Bag, name: &str) -> kitti2pgm::source::bag::Messages {
    let topic = bag
        .topic(Some(name), kitti2pgm::source::pointcloud2::TYPE_NAME)
        .unwrap();
    bag.messages(&topic)
}

fn unpack_json(args: &[&str]) -> (i32, serde_json::Value, String) {
    let mut a = vec!["unpack"];
    a.extend_from_slice(args);
    a.push("--json");
    let (code, out, err) = run_text(&a);
    let v = serde_json::from_str(&out).unwrap_or(serde_json::Value::Null);
    (code, v, err)
}

#[test]
fn unpacks_real_scans_byte_for_byte_and_converts_them_like_the_pcd_folder() {
    let t = tmp();
    let root = t.path().join("root");
    let (code, j, err) =
        unpack_json(&[s(&bag()), "--topic", "/velodyne_points", "--out", s(&root)]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["frames_written"], 2);
    assert_eq!(j["first_stamp"], "1673400472.138016708");
    assert_eq!(j["frame_ids"], serde_json::json!(["velodyne"]));
    let seq = root.join("sequences/00");
    let original = std::fs::read(vlp16()).unwrap();
    // The little-endian and the big-endian message both give the driver's own PCD back.
    for f in ["000000.pcd", "000001.pcd"] {
        assert!(
            std::fs::read(seq.join("velodyne").join(f)).unwrap() == original,
            "{f}"
        );
    }
    let times = std::fs::read_to_string(seq.join("times.txt")).unwrap();
    assert_eq!(times, "0.000000000\n0.100000000\n");
    let (code, out, err) = run_text(&["check", s(&root), "--json"]);
    assert_eq!(code, 0, "{out}{err}");
    // convert reads the unpacked sequence as it reads the PCD folder.
    let (a, b) = (t.path().join("a"), t.path().join("b"));
    for (src, out) in [(root.as_path(), &a), (&fixture("own_lidar"), &b)] {
        let (code, _, err) = run_text(&[
            "convert",
            s(src),
            "--out",
            s(out),
            "--sensor",
            "vlp16",
            "--all-frames",
            "--cols",
            "1024",
        ]);
        assert_eq!(code, 0, "{err}");
    }
    let npy = |d: &Path, f: &str| std::fs::read(d.join("lidar_2d").join(f)).unwrap();
    assert!(npy(&a, "00_000000.npy") == npy(&b, "00_000000.npy"));
    assert!(npy(&a, "00_000001.npy") == npy(&b, "00_000000.npy"));
}

#[test]
fn the_reader_gives_what_the_pcd_reader_gives() {
    let bag = Bag::open(&bag().join("own_lidar_bag.mcap")).unwrap();
    let expected = pcd::read(&vlp16()).unwrap();
    let mut n = 0;
    for m in messages_of(&bag, "/velodyne_points") {
        let m = m.unwrap().message().unwrap();
        let msg = PointCloud2::decode(&m.data, Path::new("bag")).unwrap();
        assert_eq!(msg.layout.big_endian, m.index == 1);
        let cloud = msg.cloud(Path::new("bag")).unwrap();
        assert_eq!(cloud, expected);
        assert!(cloud.ring.is_some());
        n += 1;
    }
    assert_eq!(n, 2);
    let pandar = fixture("lidars/hesai/Pandar40P_1673400149711850138.pcd");
    let m = messages_of(&bag, "/pandar_points").next().unwrap();
    let m = m.unwrap().message().unwrap();
    let msg = PointCloud2::decode(&m.data, Path::new("bag")).unwrap();
    assert_eq!(
        msg.cloud(Path::new("bag")).unwrap(),
        pcd::read(&pandar).unwrap()
    );
    assert_eq!(msg.frame_id, "hesai_lidar");
}

#[test]
fn topics_are_listed_and_a_missing_or_wrong_topic_names_the_point_cloud_topics() {
    let mcap = bag().join("own_lidar_bag.mcap");
    let (code, j, err) = unpack_json(&[s(&mcap), "--list"]);
    assert_eq!(code, 0, "{err}");
    let names: Vec<(&str, u64)> = j
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["topic"].as_str().unwrap(),
                t["messages"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        names,
        [
            ("/pandar_points", 1),
            ("/rosout_text", 1),
            ("/velodyne_points", 2)
        ]
    );
    let out = tmp();
    let o = s(out.path());
    for (topic, says) in [
        (None, "no topic given (--topic)"),
        (Some("/nope"), "no topic /nope"),
        (
            Some("/rosout_text"),
            "/rosout_text is std_msgs/msg/String, not sensor_msgs/msg/PointCloud2",
        ),
    ] {
        let mut a = vec!["unpack", s(&mcap), "--out", o];
        if let Some(t) = topic {
            a.extend(["--topic", t]);
        }
        let (code, _, err) = run_text(&a);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains(says), "{err}");
        assert!(
            err.contains("/pandar_points (1 message), /velodyne_points (2 messages)"),
            "{err}"
        );
    }
    assert!(!out.path().join("sequences").exists());
}

#[test]
fn a_rerun_is_refused_unless_overwrite_which_removes_stale_scans() {
    let t = tmp();
    let root = t.path().join("root");
    let args = |extra: &'static [&'static str]| {
        let mut a = vec![
            s(&bag()).to_string(),
            "--topic".into(),
            "/velodyne_points".into(),
        ];
        a.extend(["--out".into(), s(&root).to_string()]);
        a.extend(extra.iter().map(|e| e.to_string()));
        a
    };
    let call = |a: Vec<String>| {
        let refs: Vec<&str> = a.iter().map(|x| x.as_str()).collect();
        unpack_json(&refs)
    };
    assert_eq!(call(args(&[])).0, 0);
    let (code, _, err) = call(args(&[]));
    assert_eq!(code, 1);
    assert!(
        err.contains("already holds 2 scans") && err.contains("--overwrite"),
        "{err}"
    );
    let stale = root.join("sequences/00/velodyne/000007.pcd");
    std::fs::copy(vlp16(), &stale).unwrap();
    let (code, j, err) = call(args(&["--overwrite"]));
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["removed_stale"], 1);
    assert!(!stale.exists());
    // Another sequence of the same root is a new bag.
    let (code, j, _) = call(args(&["--sequence", "3"]));
    assert_eq!((code, &j["frames_written"]), (0, &serde_json::json!(2)));
    assert!(root.join("sequences/03/velodyne/000001.pcd").exists());
}

/// A PointCloud2 of `n` points (x, y, z float32 at 0, 4, 8) serialised as little-endian CDR.
pub(super) fn cdr_cloud(n: u32, point_step: u32, stamp_sec: i32) -> Vec<u8> {
    let mut b: Vec<u8> = vec![0, 1, 0, 0];
    let pad = |b: &mut Vec<u8>, a: usize| {
        while !(b.len() - 4).is_multiple_of(a) {
            b.push(0);
        }
    };
    let u32_ = |b: &mut Vec<u8>, v: u32| {
        pad(b, 4);
        b.extend(v.to_le_bytes());
    };
    let string = |b: &mut Vec<u8>, v: &str| {
        u32_(b, v.len() as u32 + 1);
        b.extend(v.as_bytes());
        b.push(0);
    };
    u32_(&mut b, stamp_sec as u32);
    u32_(&mut b, 5);
    string(&mut b, "lidar");
    u32_(&mut b, 1);
    u32_(&mut b, n);
    u32_(&mut b, 3);
    for (i, name) in ["x", "y", "z"].iter().enumerate() {
        string(&mut b, name);
        u32_(&mut b, 4 * i as u32);
        b.push(7);
        u32_(&mut b, 1);
    }
    b.push(0);
    u32_(&mut b, point_step);
    u32_(&mut b, point_step * n);
    u32_(&mut b, point_step * n);
    for i in 0..n * point_step / 4 {
        b.extend((1.0 + i as f32).to_le_bytes());
    }
    b.push(1);
    b
}

/// A bare `.mcap` with `messages` on `/points` (PointCloud2, CDR), written by the mcap crate
/// with its default options (zstd chunks).
fn write_mcap(path: &Path, messages: &[Vec<u8>]) {
    write_mcap_with(path, messages, mcap::WriteOptions::new());
}

#[test]
fn a_bad_message_fails_its_frame_and_the_others_are_written() {
    let t = tmp();
    let mcap = t.path().join("bad.mcap");
    // point_step 8 is smaller than the fields (z ends at byte 12).
    write_mcap(
        &mcap,
        &[cdr_cloud(3, 12, 7), cdr_cloud(3, 8, 8), cdr_cloud(2, 16, 9)],
    );
    let root = t.path().join("root");
    let (code, j, err) = unpack_json(&[s(&mcap), "--topic", "/points", "--out", s(&root)]);
    assert_eq!(code, 3, "{err}");
    assert_eq!(j["frames_written"], 2);
    let f = &j["failures"][0];
    assert_eq!(f["frame"], 1);
    let e = f["error"].as_str().unwrap();
    assert!(
        e.contains("bad.mcap/message 1") && e.contains("beyond the 8-byte point record"),
        "{e}"
    );
    let velodyne = root.join("sequences/00/velodyne");
    assert!(velodyne.join("000000.pcd").exists() && velodyne.join("000002.pcd").exists());
    assert!(!velodyne.join("000001.pcd").exists());
    assert_eq!(pcd::read(&velodyne.join("000002.pcd")).unwrap().len(), 2);
    // The failed frame's times.txt line is its log time; the summary says so.
    assert_eq!(j["log_time_frames"], serde_json::json!([1]));
}

#[test]
fn a_truncated_bag_keeps_what_was_read_and_names_the_file() {
    let t = tmp();
    let whole = t.path().join("whole.mcap");
    let many: Vec<Vec<u8>> = (0..40).map(|i| cdr_cloud(2000, 16, i)).collect();
    write_mcap(&whole, &many);
    let bytes = std::fs::read(&whole).unwrap();
    let cut = t.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
    let root = t.path().join("root");
    let (code, j, err) = unpack_json(&[s(&cut), "--topic", "/points", "--out", s(&root)]);
    // Without its summary the topic list comes from a pass over the records.
    assert_eq!(code, 3, "{err}");
    let written = j["frames_written"].as_u64().unwrap();
    assert!(written > 0 && written < 40, "{j}");
    let e = j["failures"][0]["error"].as_str().unwrap();
    assert!(e.contains("breaks off") && e.contains("cut.mcap"), "{j}");
    let (code, out, err) = run_text(&["unpack", s(&cut), "--list"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("/points"), "{out}");
}

#[test]
fn a_bag_of_another_storage_or_no_bag_is_named() {
    let t = tmp();
    let dir = t.path().join("db3bag");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths: [db3bag_0.db3]\n",
    )
    .unwrap();
    let (code, _, err) = run_text(&["unpack", s(&dir), "--list"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("metadata.yaml")
            && err.contains("sqlite3")
            && err.contains("--dst-storage mcap"),
        "{err}"
    );
    let db3 = t.path().join("run_0.db3");
    std::fs::write(&db3, b"SQLite format 3\0").unwrap();
    let (code, _, err) = run_text(&["unpack", s(&db3), "--list"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("run_0.db3") && err.contains("sqlite3"),
        "{err}"
    );
    // A topic without messages unpacks nothing: exit 1, said.
    let none = t.path().join("none.mcap");
    write_mcap(&none, &[]);
    let (code, _, err) = run_text(&[
        "unpack",
        s(&none),
        "--topic",
        "/points",
        "--out",
        s(&t.path().join("o")),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("/points has no message to unpack"), "{err}");
    let empty = t.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let (code, _, err) = run_text(&["unpack", s(&empty), "--list"]);
    assert_eq!(code, 1);
    assert!(err.contains("without metadata.yaml"), "{err}");
    let (code, _, err) = run_text(&["unpack", s(&vlp16()), "--list"]);
    assert_eq!(code, 1);
    assert!(err.contains("vlp16_1673400472138016708.pcd"), "{err}");
}

/// A sequence of one x, y, z PCD: the VLP-16 scan's points raised by `lift` metres.
fn xyz_sequence(dir: &Path, lift: f32) -> PathBuf {
    let cloud = pcd::read(&vlp16()).unwrap();
    let layout = kitti2pgm::source::PointLayout::packed(&[
        ("x", kitti2pgm::source::FieldType::F32),
        ("y", kitti2pgm::source::FieldType::F32),
        ("z", kitti2pgm::source::FieldType::F32),
    ]);
    let records: Vec<u8> = cloud
        .points
        .iter()
        .flat_map(|p| [p.x, p.y, p.z + lift])
        .flat_map(f32::to_le_bytes)
        .collect();
    let seq = dir.join("sequences/00/velodyne");
    std::fs::create_dir_all(&seq).unwrap();
    let bytes = pcd::encode(&layout, cloud.len(), 1, &records);
    std::fs::write(seq.join("000000.pcd"), bytes).unwrap();
    dir.to_path_buf()
}

#[test]
fn check_warns_when_the_points_are_not_in_the_sensor_s_frame() {
    let t = tmp();
    let beam_model = |root: &Path, extra: &[&str]| {
        let mut a = vec!["check", s(root), "--json"];
        a.extend_from_slice(extra);
        let (code, out, err) = run_text(&a);
        let j: serde_json::Value =
            serde_json::from_str(&out).unwrap_or_else(|_| panic!("{out}{err}"));
        let f: Vec<serde_json::Value> = j["findings"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["check"] == "beam-model")
            .cloned()
            .collect();
        (code, f)
    };
    // The driver's cloud, without its ring field: every point on a beam.
    let level = xyz_sequence(&t.path().join("level"), 0.0);
    assert_eq!(beam_model(&level, &["--sensor", "vlp16"]).1.len(), 0);
    // The same points 1.8 m up (a cloud in base_link): most fit no beam.
    let lifted = xyz_sequence(&t.path().join("lifted"), 1.8);
    let (code, f) = beam_model(&lifted, &["--sensor", "vlp16"]);
    assert_eq!(code, 3);
    assert_eq!(f.len(), 1);
    assert_eq!(f[0]["severity"], "error");
    let m = f[0]["message"].as_str().unwrap();
    assert!(
        m.contains("fit no beam of VLP-16") && m.contains("not in the sensor's frame"),
        "{m}"
    );
    // Its pose given, the points are back in the sensor's frame: nothing to say, and convert
    // puts every point on a beam.
    let pose = ["--sensor", "vlp16", "--sensor-pose", "0,0,1.8"];
    assert_eq!(beam_model(&lifted, &pose).1.len(), 0);
    let out = t.path().join("out");
    let mut a = vec![
        "convert",
        s(&lifted),
        "--out",
        s(&out),
        "--all-frames",
        "--json",
    ];
    a.extend_from_slice(&pose);
    let (code, j, err) = {
        let (code, o, e) = run_text(&a);
        (
            code,
            serde_json::from_str::<serde_json::Value>(&o).unwrap_or_default(),
            e,
        )
    };
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (&j["off_model"], &j["beam_table_frames"]),
        (&serde_json::json!(0), &serde_json::json!(1))
    );
    assert_eq!(
        j["params"]["map"]["sensor"]["pose"]["xyz"],
        serde_json::json!([0.0, 0.0, 1.8])
    );
    let (code, _, err) = run_text(&[
        "convert",
        s(&lifted),
        "--out",
        s(&out),
        "--sensor-pose",
        "0,0,1",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--sensor-pose needs the sensor"), "{err}");
    // Without a sensor nothing is said; the threshold is the user's.
    assert_eq!(beam_model(&lifted, &[]).1.len(), 0);
    let (_, f) = beam_model(
        &lifted,
        &["--sensor", "vlp16", "--set", "beam-model.error-share=0.99"],
    );
    assert_eq!(f[0]["severity"], "warning");
    // A ring field is checked against the sensor's beams: the VLP-16's 16 channels against an
    // 8-beam table are a read error naming the scan.
    let csv = t.path().join("eight.csv");
    let rows: Vec<String> = (1..=8).map(|i| format!("{i},{},0.0", 15 - 4 * i)).collect();
    std::fs::write(
        &csv,
        format!("Laser id,Elevation,Azimuth\n{}\n", rows.join("\n")),
    )
    .unwrap();
    let (code, out, _) = run_text(&[
        "check",
        s(&fixture("own_lidar")),
        "--sensor-calibration",
        s(&csv),
    ]);
    assert_eq!(code, 3, "{out}");
    assert!(
        out.contains("000000.pcd") && out.contains("but the sensor has 8 beams"),
        "{out}"
    );
}

/// `messages` on `/points` in a bare `.mcap` written with `options` (chunks compressed or not,
/// or no chunks), message `i` logged at time `i`.
fn write_mcap_with(path: &Path, messages: &[Vec<u8>], options: mcap::WriteOptions) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = options.create(file).unwrap();
    let schema = w
        .add_schema("sensor_msgs/msg/PointCloud2", "ros2msg", b"")
        .unwrap();
    let ch = w
        .add_channel(schema, "/points", "cdr", &Default::default())
        .unwrap();
    for (i, m) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&header, m).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn every_chunk_layout_reads_the_same_messages_and_damage_is_named() {
    let t = tmp();
    let messages: Vec<Vec<u8>> = (0..12).map(|i| cdr_cloud(300 + i, 16, i as i32)).collect();
    let layouts = [
        ("plain", mcap::WriteOptions::new().compression(None)),
        (
            "zstd",
            mcap::WriteOptions::new().compression(Some(mcap::Compression::Zstd)),
        ),
        (
            "lz4",
            mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4)),
        ),
        ("unchunked", mcap::WriteOptions::new().use_chunks(false)),
        // Small chunks: several messages, and several chunks, one after the other.
        (
            "small",
            mcap::WriteOptions::new()
                .compression(None)
                .chunk_size(Some(4000)),
        ),
    ];
    for (name, options) in layouts {
        let path = t.path().join(format!("{name}.mcap"));
        write_mcap_with(&path, &messages, options);
        let bag = Bag::open(&path).unwrap();
        let read: Vec<_> = (messages_of(&bag, "/points"))
            .map(|m| m.unwrap().message().unwrap())
            .collect();
        assert_eq!(read.len(), messages.len(), "{name}");
        for (i, (m, want)) in read.iter().zip(&messages).enumerate() {
            assert_eq!((m.index, m.log_time), (i as u64, i as u64), "{name}");
            assert_eq!(&m.data, want, "{name} message {i}");
            assert_eq!(m.file, path);
        }
        // Read in place, message by message, the same bytes.
        let mut stream = messages_of(&bag, "/points");
        let mut i = 0;
        while let Some(same) = stream.next_with(|m| m.data == messages[i]) {
            assert!(same.unwrap().message().unwrap(), "{name} message {i}");
            i += 1;
        }
        assert_eq!(i, messages.len());
        assert!(stream.next_with(|_| ()).is_none());
    }
    // Not MCAP at all.
    let text = t.path().join("notes.mcap");
    std::fs::write(&text, "not a bag").unwrap();
    let topic = kitti2pgm::source::bag::Topic {
        name: "/points".into(),
        type_name: kitti2pgm::source::pointcloud2::TYPE_NAME.into(),
        encoding: "cdr".into(),
        messages: 0,
    };
    let e = Bag::open(&text)
        .unwrap()
        .messages(&topic)
        .next()
        .unwrap()
        .unwrap_err();
    assert!(
        e.to_string().contains("notes.mcap") && e.to_string().contains("MCAP magic"),
        "{e}"
    );
}

#[test]
fn a_bag_given_to_convert_or_check_is_named_with_the_command_that_reads_it() {
    let t = tmp();
    let (out, fixture) = (t.path().join("out"), bag());
    // The fixture bag has two point cloud topics: both listed.
    for cmd in ["convert", "check"] {
        let mut args = vec![cmd, s(&fixture)];
        if cmd == "convert" {
            args.extend(["--out", s(&out)]);
        }
        let (code, _, err) = run_text(&args);
        assert_eq!(code, 1, "{cmd}");
        assert!(
            err.contains("a ROS 2 bag")
                && err.contains("kitti2pgm unpack")
                && err.contains("/pandar_points, /velodyne_points"),
            "{err}"
        );
    }
    // A bare .mcap with one point cloud topic: that topic is in the command.
    let one = t.path().join("one.mcap");
    write_mcap(&one, &[cdr_cloud(3, 16, 1)]);
    let (code, _, err) = run_text(&["convert", s(&one), "--out", s(&out)]);
    assert_eq!(code, 1);
    assert!(err.contains("--topic /points --out ROOT"), "{err}");
    // ROS 1 and sqlite3 bags: how to convert them first.
    for (name, kind) in [("run.bag", "ROS 1"), ("run.db3", "sqlite3")] {
        let p = t.path().join(name);
        std::fs::write(&p, b"#ROSBAG V2.0\n").unwrap();
        let (code, _, err) = run_text(&["convert", s(&p), "--out", s(&out)]);
        assert_eq!(code, 1);
        assert!(
            err.contains(kind) && err.contains("rosbags-convert"),
            "{err}"
        );
    }
    assert!(!out.exists());
}

/// A bag of one topic `/points` written by the mcap crate with `options`: each message on the
/// channel of its type (`sensor_msgs/msg/PointCloud2` or another), log time = its header stamp
/// (`i` s and 5 ns, as [`cdr_cloud`] stamps message `i`) so that `times.txt` is the same
/// whether a frame is read or lost.
pub(super) fn write_typed(path: &Path, messages: &[(&str, Vec<u8>)], options: mcap::WriteOptions) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = options.create(file).unwrap();
    let mut channels = std::collections::HashMap::new();
    for (i, (ty, data)) in messages.iter().enumerate() {
        let ch = *channels.entry(*ty).or_insert_with(|| {
            let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
            w.add_channel(schema, "/points", "cdr", &Default::default())
                .unwrap()
        });
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: i as u64 * 1_000_000_000 + 5,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
}

/// The chunk records of an MCAP file: (where the record's body starts, where its compressed
/// data starts, where it ends).
fn chunks(bytes: &[u8]) -> Vec<(usize, usize, usize)> {
    let mut at = 8;
    let mut out = Vec::new();
    while at + 9 <= bytes.len() {
        let op = bytes[at];
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        let body = at + 9;
        if op == 0x06 {
            // message start and end times, uncompressed size, CRC, compression string, size.
            let name = u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap());
            out.push((body, body + 32 + name as usize + 8, body + len));
        }
        if op == 0x0F {
            break; // the footer
        }
        at = body + len;
    }
    out
}

fn unpack_to(bag: &Path, root: &Path) -> (i32, serde_json::Value, String) {
    unpack_json(&[s(bag), "--topic", "/points", "--out", s(root)])
}

/// Issue 47, defects 2 and 3: a flipped byte in a chunk (uncompressed: rosbag2's default, whose
/// CRC is now checked; zstd; lz4) fails that chunk's frame alone, named with its log time in
/// `times.txt`, and the walk goes on to the later chunks; a chunk whose CRC is 0 has none.
#[test]
fn a_damaged_chunk_fails_its_frames_alone() {
    let t = tmp();
    let clouds: Vec<(&str, Vec<u8>)> = (0..5)
        .map(|i| {
            (
                kitti2pgm::source::pointcloud2::TYPE_NAME,
                cdr_cloud(300, 16, i),
            )
        })
        .collect();
    for (name, compression) in [
        ("plain", None),
        ("zstd", Some(mcap::Compression::Zstd)),
        ("lz4", Some(mcap::Compression::Lz4)),
    ] {
        let bag = t.path().join(format!("{name}.mcap"));
        let options = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(Some(1));
        write_typed(&bag, &clouds, options);
        let clean = t.path().join(format!("{name}-clean"));
        let (code, j, err) = unpack_to(&bag, &clean);
        assert_eq!((code, &j["frames_written"]), (0, &json!(5)), "{err}");
        let bytes = std::fs::read(&bag).unwrap();
        // The schema and channel records in a chunk of their own, then a chunk a message.
        let all = chunks(&bytes);
        assert_eq!(all.len(), 6, "{name}");
        let found = &all[1..];
        for k in [0, 2] {
            let (_, data, end) = found[k];
            let mut bad = bytes.clone();
            bad[(data + end) / 2] ^= 0x10;
            let damaged = t.path().join(format!("{name}-{k}.mcap"));
            std::fs::write(&damaged, &bad).unwrap();
            let root = t.path().join(format!("{name}-{k}"));
            let (code, j, err) = unpack_to(&damaged, &root);
            assert_eq!(code, 3, "{name} {k}: {err} {j}");
            assert_eq!(j["frames_written"], 4, "{name} {k}: {j}");
            assert_eq!(j["messages"], 5, "{name} {k}: {j}");
            let f = j["failures"].as_array().unwrap();
            assert_eq!(f.len(), 1, "{name} {k}: {j}");
            assert_eq!(f[0]["frame"], k, "{j}");
            let e = f[0]["error"].as_str().unwrap();
            assert!(
                e.contains(&format!("{name}-{k}.mcap")) && e.contains("chunk"),
                "{e}"
            );
            assert_eq!(j["log_time_frames"], json!([k]));
            let seq = |r: &Path| r.join("sequences/00");
            for i in (0..5).filter(|&i| i != k) {
                let p = format!("velodyne/{i:06}.pcd");
                assert!(
                    std::fs::read(seq(&root).join(&p)).unwrap()
                        == std::fs::read(seq(&clean).join(&p)).unwrap(),
                    "{name} {k}: frame {i}"
                );
            }
            assert!(!seq(&root).join(format!("velodyne/{k:06}.pcd")).exists());
            let times = |r: &Path| std::fs::read_to_string(seq(r).join("times.txt")).unwrap();
            assert_eq!(times(&root), times(&clean), "{name} {k}");
        }
        // The chunk of the channel records damaged: the file's summary still names the
        // channel, so every frame is read and the damage is named.
        let (_, data, end) = all[0];
        let mut bad = bytes.clone();
        bad[(data + end) / 2] ^= 0x10;
        let damaged = t.path().join(format!("{name}-channels.mcap"));
        std::fs::write(&damaged, &bad).unwrap();
        let (code, j, err) = unpack_to(&damaged, &t.path().join(format!("{name}-channels")));
        assert_eq!((code, &j["frames_written"]), (3, &json!(5)), "{err} {j}");
        assert_eq!(j["damaged"].as_array().unwrap().len(), 1, "{j}");
        if compression.is_none() {
            // CRC 0: the chunk has none, and is read as it is.
            let mut none = bytes.clone();
            for &(body, _, _) in found {
                none[body + 24..body + 28].fill(0);
            }
            let nocrc = t.path().join("nocrc.mcap");
            std::fs::write(&nocrc, &none).unwrap();
            let (code, j, err) = unpack_to(&nocrc, &t.path().join("nocrc"));
            assert_eq!((code, &j["frames_written"]), (0, &json!(5)), "{err}");
        }
    }
}

/// Issue 47, defect 4: a topic is channels: the PointCloud2 messages of `/points` unpack and
/// the `std_msgs/msg/String` one beside them is counted as passed over, whatever the chunks;
/// `--list` names both types.
#[test]
fn a_message_of_another_type_on_the_topic_is_passed_over() {
    let t = tmp();
    let pc2 = kitti2pgm::source::pointcloud2::TYPE_NAME;
    let text = "std_msgs/msg/String";
    let messages = vec![
        (pc2, cdr_cloud(30, 16, 0)),
        (pc2, cdr_cloud(30, 16, 1)),
        (text, vec![0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0]),
        (pc2, cdr_cloud(30, 16, 3)),
        (pc2, cdr_cloud(30, 16, 4)),
    ];
    for (name, compression) in [("plain", None), ("zstd", Some(mcap::Compression::Zstd))] {
        let bag = t.path().join(format!("{name}.mcap"));
        write_typed(
            &bag,
            &messages,
            mcap::WriteOptions::new().compression(compression),
        );
        let root = t.path().join(name);
        let (code, j, err) = unpack_to(&bag, &root);
        assert_eq!(code, 0, "{name}: {err}");
        assert_eq!(j["frames_written"], 4, "{j}");
        assert_eq!(j["skipped_other_types"], 1, "{j}");
        let (code, out, err) = run_text(&["unpack", s(&bag), "--list", "--json"]);
        assert_eq!(code, 0, "{err}");
        let listed: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(
            listed,
            json!([{"topic": "/points", "type": pc2, "encoding": "cdr", "messages": 4},
                   {"topic": "/points", "type": text, "encoding": "cdr", "messages": 1}])
        );
    }
}

/// A PointCloud2 message of `n` records of `step` bytes (`data`) with `fields` (name, offset,
/// datatype, count), in either byte order.
fn cdr_message(
    fields: &[(&str, u32, u8, u32)],
    step: u32,
    n: u32,
    data: &[u8],
    be: bool,
) -> Vec<u8> {
    let mut b: Vec<u8> = vec![0, if be { 0 } else { 1 }, 0, 0];
    let u32_ = |b: &mut Vec<u8>, v: u32| {
        while !(b.len() - 4).is_multiple_of(4) {
            b.push(0);
        }
        b.extend(if be { v.to_be_bytes() } else { v.to_le_bytes() });
    };
    let string = |b: &mut Vec<u8>, v: &str| {
        u32_(b, v.len() as u32 + 1);
        b.extend(v.as_bytes());
        b.push(0);
    };
    u32_(&mut b, 7);
    u32_(&mut b, 0);
    string(&mut b, "lidar");
    u32_(&mut b, 1);
    u32_(&mut b, n);
    u32_(&mut b, fields.len() as u32);
    for &(name, offset, datatype, count) in fields {
        string(&mut b, name);
        u32_(&mut b, offset);
        b.push(datatype);
        u32_(&mut b, count);
    }
    b.push(be as u8);
    u32_(&mut b, step);
    u32_(&mut b, step * n);
    u32_(&mut b, data.len() as u32);
    b.extend(data);
    b.push(1);
    b
}

/// Issue 47, defect 5: what unpack writes, convert reads. For every field kind the decoder
/// accepts (PointField's eight datatypes as the intensity, the ring and an extra field; counts
/// 0, 1 and 3; both byte orders; padding between fields), the PCD that unpack writes decodes to
/// the cloud that `read_bag` decodes from the message; a zero-wide x is no x, refused by both.
#[test]
fn every_field_kind_round_trips_through_unpack() {
    let names = ["i8", "u8", "i16", "u16", "i32", "u32", "f32", "f64"];
    let size = |dt: u8| [1, 1, 2, 2, 4, 4, 4, 8][dt as usize - 1] as u32;
    let what = Path::new("message");
    let mut cases = 0;
    for dt in 1..=8u8 {
        for count in [0u32, 1, 3] {
            for be in [false, true] {
                for role in ["intensity", "ring", "extra"] {
                    // x, y, z float32, 2 bytes of padding, the field, a zero-wide pad field.
                    let at = 14;
                    let step = at + size(dt) * count + 3;
                    let fields = [
                        ("x", 0, 7, 1),
                        ("y", 4, 7, 1),
                        ("z", 8, 7, 1),
                        (role, at, dt, count),
                        ("pad", step - 1, 2, 0),
                    ];
                    let n = 7u32;
                    let data: Vec<u8> = (0..n * step)
                        .map(|i| {
                            let (p, o) = (i / step, i % step);
                            // Small finite coordinates (the top byte of each float fixed).
                            match (o % 4, o < 12, be) {
                                (3, true, false) | (0, true, true) => 0x40,
                                _ => (p * 31 + o * 7) as u8 & 0x3f,
                            }
                        })
                        .collect();
                    let msg_bytes = cdr_message(&fields, step, n, &data, be);
                    let msg = PointCloud2::decode(&msg_bytes, what).unwrap();
                    let from_message = msg.cloud(what);
                    let (layout, records) = msg.packed();
                    let file = pcd::encode(&layout, n as usize, 1, &records);
                    let from_pcd = pcd::decode(&file, what);
                    match (from_message, from_pcd) {
                        (Ok(a), Ok(b)) => {
                            assert_eq!(a, b, "{} x{count} {role} be={be}", names[dt as usize - 1])
                        }
                        // The same refusal from both (a ring of values no beam id has).
                        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                        (a, b) => {
                            panic!("{} x{count} {role}: {a:?} / {b:?}", names[dt as usize - 1])
                        }
                    }
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, 8 * 3 * 2 * 3);
    // A zero-wide x holds nothing: no x, the same refusal from both readers.
    let data = vec![0x20u8; 16 * 2];
    let fields = [
        ("x", 0, 7, 0),
        ("y", 4, 7, 1),
        ("z", 8, 7, 1),
        ("x2", 12, 7, 1),
    ];
    let bytes = cdr_message(&fields, 16, 2, &data, false);
    let e = PointCloud2::decode(&bytes, what).unwrap_err().to_string();
    assert!(e.contains("no x field"), "{e}");
}

/// Issue 47, defect 5 end to end: a message with a zero-wide padding field unpacks to a PCD
/// (`COUNT 0`) that convert reads; a message whose x is zero-wide fails its frame in unpack
/// (nothing written that convert would refuse).
#[test]
fn unpack_writes_only_what_convert_reads() {
    let t = tmp();
    let pc2 = kitti2pgm::source::pointcloud2::TYPE_NAME;
    let data: Vec<u8> = (0..40u32)
        .flat_map(|i| {
            let a = i as f32 * 0.1 + 2.0;
            [
                a.to_le_bytes(),
                (a * 0.5).to_le_bytes(),
                (-0.3f32).to_le_bytes(),
                [0; 4],
            ]
            .concat()
        })
        .collect();
    let good = [
        ("x", 0, 7, 1),
        ("y", 4, 7, 1),
        ("z", 8, 7, 1),
        ("_", 12, 7, 0),
    ];
    let bad = [("x", 0, 7, 0), ("y", 4, 7, 1), ("z", 8, 7, 1)];
    let bag = t.path().join("count0.mcap");
    write_typed(
        &bag,
        &[
            (pc2, cdr_message(&good, 16, 40, &data, false)),
            (pc2, cdr_message(&bad, 16, 40, &data, false)),
            (pc2, cdr_message(&good, 16, 40, &data, false)),
        ],
        mcap::WriteOptions::new(),
    );
    let root = t.path().join("root");
    let (code, j, err) = unpack_to(&bag, &root);
    assert_eq!((code, &j["frames_written"]), (3, &json!(2)), "{err} {j}");
    assert_eq!(j["failures"][0]["frame"], 1);
    let head = std::fs::read(root.join("sequences/00/velodyne/000000.pcd")).unwrap();
    assert!(String::from_utf8_lossy(&head[..200]).contains("COUNT 1 1 1 0"));
    let (code, j, err) = super::util::convert_json(
        &root,
        &t.path().join("conv"),
        &["--sensor", "vlp16", "--all-frames", "--cols", "512"],
    );
    assert_eq!(code, 0, "{err} {j}");
    assert_eq!(j["frames_converted"], 2, "{j}");
}

/// Issue 47, defects 7 and 8 for bags: a root another run holds is refused (two unpacks into
/// one root at once cannot mix their sequences); while an unpack runs its `unpack.json` says
/// `complete: false`, which the readers refuse; at the end it says true.
#[test]
fn unpack_holds_the_root_and_marks_its_sequence_unfinished_until_the_end() {
    let t = tmp();
    let root = t.path().join("root");
    std::fs::create_dir(&root).unwrap();
    let held = kitti2pgm::convert::resume::lock_dir(&root).unwrap();
    let v = super::util::fails_with(
        &[
            "unpack",
            s(&bag()),
            "--topic",
            "/velodyne_points",
            "--out",
            s(&root),
        ],
        "locked",
    );
    assert_eq!(v["exit"], 1);
    assert!(!root.join("sequences").exists());
    drop(held);
    let b = Bag::open(&bag()).unwrap();
    let topic = b
        .topic(
            Some("/velodyne_points"),
            kitti2pgm::source::pointcloud2::TYPE_NAME,
        )
        .unwrap();
    let opts = kitti2pgm::convert::unpack::UnpackOptions {
        out: root.clone(),
        sequence: 0,
        overwrite: false,
        durability: kitti2pgm::format::Durability::default(),
        sensor_frame: None,
    };
    let marker = root.join("sequences/00/unpack.json");
    let seen = std::sync::Mutex::new(Vec::new());
    let s = kitti2pgm::convert::unpack::unpack(&b, &topic, &opts, &|_| {
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&marker).unwrap()).unwrap();
        seen.lock().unwrap().push(j["complete"].clone());
        // Meanwhile the sequence is refused.
        let e = kitti2pgm::source::kitti::discover_as(&root, None).unwrap_err();
        assert!(
            matches!(e, kitti2pgm::Error::UnfinishedUnpack { .. }),
            "{e}"
        );
    })
    .unwrap();
    assert!(s.complete);
    assert_eq!(*seen.lock().unwrap(), vec![json!(false), json!(false)]);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&marker).unwrap()).unwrap();
    assert_eq!(j["complete"], true);
    assert!(kitti2pgm::source::kitti::discover_as(&root, None).is_ok());
}

/// Issue 47's smaller defects on bags: a `metadata.yaml` listing one file twice, an `.mcap`
/// shorter than its magic, a missing file: each named once, without the OS error twice.
#[test]
fn small_bag_faults_are_named_plainly() {
    let t = tmp();
    let dir = t.path().join("twice");
    std::fs::create_dir(&dir).unwrap();
    std::fs::copy(bag().join("own_lidar_bag.mcap"), dir.join("a.mcap")).unwrap();
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [a.mcap, a.mcap]\n",
    )
    .unwrap();
    let (code, _, err) = run_text(&["unpack", s(&dir), "--list"]);
    assert_eq!(code, 1);
    assert!(err.contains("a.mcap twice"), "{err}");
    let short = t.path().join("short.mcap");
    std::fs::write(&short, b"\x89MC").unwrap();
    let (code, _, err) = run_text(&["unpack", s(&short), "--list"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("not an MCAP file") && !err.contains("os error"),
        "{err}"
    );
    let (code, _, err) = run_text(&["unpack", s(&t.path().join("none.mcap")), "--list"]);
    assert_eq!(code, 1);
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}
