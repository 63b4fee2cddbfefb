"""Stage 10, the grasp task shared by the simulated envs (``aas_gym``) and the real env
(``real``), without MuJoCo: its contract (``grasp``: constants, observation layout, robot
state, checks), its acoustic observation (``acoustic``: :class:`AcousticConfig`), and the rules
of an episode written once (``action``: what an action means; ``reward``: the reward terms;
``cadence``: when to record and when an episode succeeds)."""

from .acoustic import (BYTES_PER_SAMPLE, CADENCES, FEATURE_MODES, LEGACY_KEYWORDS, MAX_HISTORY, MAX_SAMPLES, N_FEATURES,
                       AcousticConfig, AcousticEnvMixin, resolve_excitation)
from .frames import AcousticFrames
from .checks import check_choice, check_flag, check_integer, check_number
from .action import GraspAction, decode_grasp_action, next_tcp_target
from .cadence import GraspHold, records_this_step, step_success
from .grasp import (HOME_TCP, MAX_DELTA, MAX_GRIP_FORCE_N, MAX_OPENING_M, STATE_LAYOUT, STATE_SIZE, RobotState,
                    check_action, check_grip_force, proprio_spaces)
from .reward import (GRASP_REWARD, GRASP_REWARD_TERMS, SUCCESS_REWARD, grasp_reward_terms, reward_total,
                     tcp_object_distance_m)

__all__ = ["AcousticConfig", "AcousticEnvMixin", "AcousticFrames", "FEATURE_MODES", "MAX_HISTORY", "BYTES_PER_SAMPLE", "CADENCES", "MAX_SAMPLES", "check_choice", "check_flag",
           "check_integer", "check_number", "GRASP_REWARD", "GRASP_REWARD_TERMS", "GraspAction", "GraspHold",
           "HOME_TCP", "LEGACY_KEYWORDS", "MAX_DELTA", "MAX_GRIP_FORCE_N", "MAX_OPENING_M", "N_FEATURES",
           "RobotState", "STATE_LAYOUT", "STATE_SIZE", "SUCCESS_REWARD", "check_action", "check_grip_force",
           "decode_grasp_action", "grasp_reward_terms", "next_tcp_target", "proprio_spaces", "records_this_step",
           "resolve_excitation", "reward_total", "step_success", "tcp_object_distance_m"]
