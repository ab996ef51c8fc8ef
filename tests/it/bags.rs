//! ROS 2 bags: `kitti2pgm unpack` and the bag reader on `fixtures/own_lidar_bag` (real VLP-16
//! and Pandar40P scans written by rosbags, an independent official writer; one message
//! big-endian), and on bad bags made here.

use std::path::{Path, PathBuf};

use kitti2pgm::source::bag::Bag;
use kitti2pgm::source::pcd;
use kitti2pgm::source::pointcloud2::PointCloud2;

use super::util::{fixture, run_text, s, tmp};

fn bag() -> PathBuf {
    fixture("own_lidar_bag")
}

fn vlp16() -> PathBuf {
    fixture("lidars/velodyne/vlp16_1673400472138016708.pcd")
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
    for m in bag.messages("/velodyne_points") {
        let m = m.unwrap();
        let msg = PointCloud2::decode(&m.data, Path::new("bag")).unwrap();
        assert_eq!(msg.layout.big_endian, m.index == 1);
        let cloud = msg.cloud(Path::new("bag")).unwrap();
        assert_eq!(cloud, expected);
        assert!(cloud.ring.is_some());
        n += 1;
    }
    assert_eq!(n, 2);
    let pandar = fixture("lidars/hesai/Pandar40P_1673400149711850138.pcd");
    let m = bag.messages("/pandar_points").next().unwrap().unwrap();
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
fn cdr_cloud(n: u32, point_step: u32, stamp_sec: i32) -> Vec<u8> {
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
        let read: Vec<_> = bag.messages("/points").map(|m| m.unwrap()).collect();
        assert_eq!(read.len(), messages.len(), "{name}");
        for (i, (m, want)) in read.iter().zip(&messages).enumerate() {
            assert_eq!((m.index, m.log_time), (i as u64, i as u64), "{name}");
            assert_eq!(&m.data, want, "{name} message {i}");
            assert_eq!(m.file, path);
        }
        // Read in place, message by message, the same bytes.
        let mut stream = bag.messages("/points");
        let mut i = 0;
        while let Some(same) = stream.next_with(|m| m.data == messages[i]) {
            assert!(same.unwrap(), "{name} message {i}");
            i += 1;
        }
        assert_eq!(i, messages.len());
        assert!(stream.next_with(|_| ()).is_none());
    }
    // A flipped byte inside a compressed chunk fails its CRC: the error names the file, and
    // the stream ends there.
    let zstd = std::fs::read(t.path().join("zstd.mcap")).unwrap();
    let mut bad = zstd.clone();
    let at = bad.len() / 3;
    bad[at] ^= 0x40;
    let damaged = t.path().join("damaged.mcap");
    std::fs::write(&damaged, &bad).unwrap();
    let results: Vec<_> = Bag::open(&damaged).unwrap().messages("/points").collect();
    let e = results.last().unwrap().as_ref().unwrap_err().to_string();
    assert!(e.contains("damaged.mcap"), "{e}");
    assert!(results[..results.len() - 1].iter().all(|r| r.is_ok()));
    // Not MCAP at all.
    let text = t.path().join("notes.mcap");
    std::fs::write(&text, "not a bag").unwrap();
    let e = Bag::open(&text)
        .unwrap()
        .messages("/points")
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
