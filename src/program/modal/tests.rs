//! Unit tests of the modal state.

use super::*;

fn w(address: &'static str, value: f64, item: usize) -> WordRef<'static> {
    WordRef {
        address,
        value,
        item,
    }
}

#[test]
fn pose_block_with_modal_components() {
    let mut m = ModalState::new(PoseStart::On);
    let b = m
        .apply(
            &[
                w("G", 1.0, 0),
                w("X", 1.0, 2),
                w("Y", 2.0, 4),
                w("Z", 3.0, 6),
                w("F", 100.0, 8),
            ],
            &[],
        )
        .unwrap();
    let (tip, axis) = b.pose.unwrap();
    assert_eq!(tip, Vector3::new(1.0, 2.0, 3.0));
    assert_eq!(axis, Vector3::z());
    assert_eq!(b.pose_items.as_slice(), [2, 4, 6]);
    let b = m
        .apply(&[w("X", 5.0, 0), w("I", 0.6, 2), w("K", 0.8, 4)], &[])
        .unwrap();
    let (tip, axis) = b.pose.unwrap();
    assert_eq!(tip, Vector3::new(5.0, 2.0, 3.0));
    assert!((axis - Vector3::new(0.6, 0.0, 0.8)).norm() < 1e-15);
    assert_eq!(b.feed, Some(100.0));
}

#[test]
fn threads_cycles_and_tilted_planes_carry_no_tool_vector() {
    // Found on the LinuxCNC corpus: their I J K switched pose mode on.
    for g in [76.0, 33.1, 6.2, 73.0] {
        let mut m = ModalState::new(PoseStart::Off);
        let b = m
            .apply(
                &[
                    w("G", g, 0),
                    w("Z", -5.0, 1),
                    w("I", -0.1, 2),
                    w("K", 1.0, 3),
                ],
                &[],
            )
            .unwrap();
        assert!(b.pose.is_none() && !m.pose_mode, "G{g}");
    }
    // A LinuxCNC lathe cycle (G71 with Q) is not Sinumerik's G71 (mm).
    let mut m = ModalState::new(PoseStart::Off);
    m.apply(&[w("G", 20.0, 0)], &[]).unwrap();
    m.apply(&[w("G", 71.0, 0), w("Q", 100.0, 1), w("I", 1.0, 2)], &[])
        .unwrap();
    assert!(!m.pose_mode);
    assert_eq!(m.units, Units::Inch);
    // G68.2 passes through outside pose mode, and is refused in it.
    let mut m = ModalState::new(PoseStart::Off);
    let b = m.apply(
        &[
            w("G", 68.2, 0),
            w("I", 0.0, 1),
            w("J", 45.0, 2),
            w("K", 0.0, 3),
        ],
        &[],
    );
    assert!(b.unwrap().pose.is_none() && !m.pose_mode);
    let mut m = ModalState::new(PoseStart::On);
    let e = m
        .apply(&[w("G", 68.2, 0), w("J", 45.0, 1)], &[])
        .unwrap_err();
    assert!(e.message.contains("a frame (G68"), "{}", e.message);
}

#[test]
fn sinumerik_frames_are_never_poses() {
    // Under TRAORI `AROT Y90.` came out with axis words appended.
    let mut m = ModalState::new(PoseStart::Off);
    m.apply(&[], &[(0, "TRAORI")]).unwrap();
    let e = m.apply(&[w("Y", 90.0, 2)], &[(0, "AROT")]).unwrap_err();
    assert_eq!(e.item, Some(0));
    // Outside pose mode a frame passes through, but pose mode may not
    // start while it is active; deleting it (`TRANS` alone, G69) allows it.
    let mut m = ModalState::new(PoseStart::Off);
    assert!(
        m.apply(&[w("X", 10.0, 2)], &[(0, "TRANS")])
            .unwrap()
            .pose
            .is_none()
    );
    let e = m.apply(&[], &[(0, "TRAORI")]).unwrap_err();
    assert!(e.message.contains("frame set earlier"), "{}", e.message);
    let mut m = ModalState::new(PoseStart::Off);
    m.apply(&[w("X", 10.0, 2)], &[(0, "TRANS")]).unwrap();
    m.apply(&[], &[(0, "TRANS")]).unwrap();
    m.apply(&[], &[(0, "TRAORI")]).unwrap();
    assert!(m.pose_mode);
}

#[test]
fn inch_and_incremental() {
    let mut m = ModalState::new(PoseStart::On);
    m.apply(&[w("G", 20.0, 0)], &[]).unwrap();
    let b = m
        .apply(
            &[
                w("G", 1.0, 0),
                w("X", 1.0, 1),
                w("Y", 0.0, 2),
                w("Z", 2.0, 3),
            ],
            &[],
        )
        .unwrap();
    assert_eq!(b.pose.unwrap().0, Vector3::new(25.4, 0.0, 50.8));
    m.apply(&[w("G", 91.0, 0)], &[]).unwrap();
    let b = m.apply(&[w("X", 1.0, 1)], &[]).unwrap();
    assert!((b.pose.unwrap().0.x - 50.8).abs() < 1e-12);
}

#[test]
fn tcp_codes_switch_pose_mode() {
    let mut m = ModalState::new(PoseStart::Off);
    let b = m
        .apply(
            &[
                w("G", 0.0, 0),
                w("X", 1.0, 1),
                w("Y", 1.0, 2),
                w("Z", 1.0, 3),
            ],
            &[],
        )
        .unwrap();
    assert!(b.pose.is_none());
    let b = m.apply(&[w("G", 43.5, 0), w("H", 1.0, 2)], &[]).unwrap();
    assert_eq!(b.tcp_codes, vec![TcpCode::FanucOn(0)]);
    assert_eq!(b.tcp_offset_items, vec![2]);
    // Machine-coordinate moves before TCP do not define the tool tip.
    assert!(m.apply(&[w("X", 2.0, 1)], &[]).is_err());
    let b = m
        .apply(&[w("X", 2.0, 1), w("Y", 1.0, 2), w("Z", 1.0, 3)], &[])
        .unwrap();
    assert!(b.pose.is_some());
    m.apply(&[w("G", 49.0, 0)], &[]).unwrap();
    assert!(m.apply(&[w("X", 2.0, 1)], &[]).unwrap().pose.is_none());
    let b = m.apply(&[], &[(0, "TRAORI")]).unwrap();
    assert_eq!(b.tcp_codes, vec![TcpCode::SiemensOn(0)]);
    let b = m
        .apply(&[w("A3", 0.0, 0), w("B3", 0.0, 1), w("C3", 1.0, 2)], &[])
        .unwrap();
    assert!(b.pose.is_some());
}

#[test]
fn errors_name_the_item() {
    let mut m = ModalState::new(PoseStart::On);
    let e = m.apply(&[w("G", 1.0, 0), w("X", 1.0, 3)], &[]).unwrap_err();
    assert!(e.message.contains("Y is not known"), "{}", e.message);
    let mut m = ModalState::new(PoseStart::On);
    m.apply(&[w("X", 0.0, 0), w("Y", 0.0, 1), w("Z", 0.0, 2)], &[])
        .unwrap();
    let e = m.apply(&[w("G", 2.0, 0), w("X", 1.0, 5)], &[]).unwrap_err();
    assert_eq!(e.item, Some(5));
    let e = m
        .apply(
            &[
                w("G", 1.0, 0),
                w("I", 0.0, 1),
                w("J", 0.0, 2),
                w("K", 0.0, 7),
            ],
            &[],
        )
        .unwrap_err();
    assert!(e.message.contains("zero"));
    let e = m
        .apply(&[w("I", 0.0, 1), w("J", 0.0, 2), w("K", 1.1, 7)], &[])
        .unwrap_err();
    assert!(e.message.contains("length"));
    let b = m
        .apply(&[w("I", 0.0, 1), w("J", 0.0, 2), w("K", 1.0004, 7)], &[])
        .unwrap();
    assert_eq!(b.warnings.len(), 1);
}

/// A lathe's cutting cycles are not followed (found in session 29: Fanuc's
/// `G71 P10 Q20` and `G70 P10 Q20` were read as Sinumerik's mm and skipped
/// by the commands that follow motion); Sinumerik's G70/G71 and a mill's
/// peck drilling G73 stay what they were.
#[test]
fn lathe_cutting_cycles_are_not_followed() {
    let cases: &[(&[(&'static str, f64)], bool)] = &[
        (&[("G", 71.0), ("P", 10.0), ("Q", 20.0), ("F", 0.25)], true),
        (&[("G", 71.0), ("U", 2.0), ("R", 0.5)], true),
        (&[("G", 70.0), ("P", 10.0), ("Q", 20.0)], true),
        (&[("G", 72.0), ("W", 2.0), ("R", 0.5)], true),
        (&[("G", 73.0), ("P", 10.0), ("Q", 20.0)], true),
        (&[("G", 74.0), ("Z", -20.0), ("Q", 5.0), ("F", 0.1)], true),
        (
            &[
                ("G", 71.0),
                ("Q", 100.0),
                ("X", 52.0),
                ("Z", 2.0),
                ("D", 1.0),
            ],
            true,
        ),
        (&[("G", 71.0)], false),
        (&[("G", 70.0), ("G", 0.0), ("X", 1.0)], false),
        (
            &[
                ("G", 73.0),
                ("X", 1.0),
                ("Y", 2.0),
                ("Z", -5.0),
                ("R", 1.0),
                ("Q", 1.0),
            ],
            false,
        ),
        (
            &[
                ("G", 74.0),
                ("X", 1.0),
                ("Y", 2.0),
                ("Z", -5.0),
                ("R", 1.0),
                ("P", 0.5),
            ],
            false,
        ),
    ];
    for (words, lathe) in cases {
        let mut m = ModalState::new(PoseStart::Off);
        let refs: Vec<WordRef<'static>> = words
            .iter()
            .enumerate()
            .map(|(i, &(a, v))| w(a, v, i))
            .collect();
        let b = m.apply(&refs, &[]).unwrap();
        let found = b
            .unfollowed
            .as_ref()
            .is_some_and(|(_, what)| what == unfollowed::LATHE_CYCLE);
        assert_eq!(found, *lathe, "{words:?}");
        if *lathe {
            assert!(b.non_modal, "{words:?}");
        }
    }
}
