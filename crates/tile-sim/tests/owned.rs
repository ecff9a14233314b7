//! The owned-output calls equal the buffer-filling ones they wrap.

use tile_sim::{Env, Task, Variation, VecEnv};

#[test]
fn env_owned_calls_match_the_buffer_calls() {
    for task in [Task::TileSuction, Task::BlockGrip, Task::Screw] {
        let (mut a, mut b) = (Env::new(task, 7), Env::new(task, 7));
        let mut obs = vec![0.0; task.obs_dim()];
        a.reset(Some(11), &mut obs).unwrap();
        assert_eq!(b.reset_owned(Some(11)).unwrap(), obs);
        let action: Vec<f32> = (0..task.act_dim()).map(|i| 0.3 - 0.1 * i as f32).collect();
        for k in 0..5 {
            let o = a.step(&action, &mut obs).unwrap();
            let (obs2, o2, info) = b.step_owned(&action).unwrap();
            assert_eq!((obs2.as_slice(), o2), (obs.as_slice(), o));
            assert_eq!(
                (info.picked, info.held, info.installed, info.fell),
                (o.picked, o.held, o.installed, o.fell)
            );
            assert_eq!(info.step, k + 1);
        }
        let rs = b.record_state();
        assert_eq!((rs.snapshot, rs.links), (a.snapshot(), a.link_poses()));
    }
}

#[test]
fn vecenv_owned_calls_match_the_buffer_calls() {
    let task = Task::BlockGrip;
    let (n, od, ad) = (3, task.obs_dim(), task.act_dim());
    let (mut a, mut b) = (VecEnv::new(task, n, 5, 1).unwrap(), VecEnv::new(task, n, 5, 1).unwrap());
    let mut obs = vec![0.0; n * od];
    a.reset(Some(4), &mut obs).unwrap();
    assert_eq!(b.reset_owned(Some(4)).unwrap(), obs);
    a.reset_mask(&[true, false, true], &mut obs).unwrap();
    assert_eq!(b.reset_mask_owned(&[true, false, true]).unwrap(), obs);
    let acts = vec![0.2; 2 * ad];
    let mut one = vec![0.0; od];
    a.reset_replay(1, 9, None, &acts, &mut one).unwrap();
    assert_eq!(b.reset_replay_owned(1, 9, None, &acts).unwrap(), one);
    let st = a.state();
    a.restore(&st, &mut obs).unwrap();
    assert_eq!(b.restore_owned(&st).unwrap(), obs);
    assert!(b.reset_replay_owned(n, 0, None, &acts).is_err());
}

#[test]
fn variation_from_options() {
    assert_eq!(Variation::from_options(Some([0.1, 0.2]), 0.5, true), Variation::robust());
    let v = Variation::from_options(Some([-0.3, -0.2]), 0.01, false);
    assert_eq!((v.object_x, v.target_jitter), ([-0.3, -0.2], 0.01));
    let d = Variation::from_options(None, 0.02, false);
    assert_eq!((d.object_x, d.target_jitter), (Variation::default().object_x, 0.02));
}
