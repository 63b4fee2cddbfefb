"""Gymnasium environments (registered by ``import aas_gym``)."""

from aas_gym.envs.acoustic_grasp import AcousticGraspEnv
from aas_gym.envs.base import AasEnv, DomainRandomization
from aas_gym.envs.contact_formation import ContactFormationEnv
from aas_gym.envs.fill_level import FillLevelEnv
from aas_gym.envs.grasp_position import GraspPositionEnv
from aas_gym.envs.object_recognition import ObjectRecognitionEnv

__all__ = ["AasEnv", "AcousticGraspEnv", "ContactFormationEnv", "DomainRandomization", "FillLevelEnv", "GraspPositionEnv", "ObjectRecognitionEnv"]
