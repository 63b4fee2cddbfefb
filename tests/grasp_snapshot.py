"""What a probe env's reset left grasped, for comparing a fast path with its reference: object
and hand poses, the target's contacts and fingertip forces, the grasp's closed-form features,
and the reset's ``info`` entries asked for."""

from __future__ import annotations

import numpy as np


def grasped_state(env, seed: int, info_keys=()) -> dict:
    """Reset ``env`` (unwrapped; its reset grasps) with ``seed`` and return the grasped state:
    ``objects`` (free joints' qpos), ``hand`` (TCP and finger qpos), ``points`` and ``kinds``
    (list) of the target's contacts, ``forces`` (actuator, mic) [N], ``features``,
    ``success`` (``info["grasp_success"]``) and ``info[k]`` under ``k`` for each of ``info_keys``."""
    _, info = env.reset(seed=seed)
    sc, d = env._scene, env.data
    c = sc.stream.read(d)[sc.bodies[0]]
    features = env.sensor.sense(env.excitation, env.duration_s, variation=env._variation,
                                rng=np.random.default_rng(0), waveform=False).features()
    return {"objects": np.concatenate([d.qpos[a:a + 7] for a, _ in sc.free_joints]),
            "hand": np.concatenate([d.qpos[sc.hand.tcp_qpos], d.qpos[sc.hand.finger_qpos]]),
            "points": c.positions_m, "kinds": c.kinds.tolist(),
            "forces": np.array([c.total_normal_force_n("actuator"), c.total_normal_force_n("mic")]),
            "features": features, "success": info["grasp_success"], **{k: info[k] for k in info_keys}}
