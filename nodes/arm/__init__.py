"""The arm's controller node kind (``joint_targets``): a sequence of joint position targets."""
