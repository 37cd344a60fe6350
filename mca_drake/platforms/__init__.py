"""What moves the occupant: one typed description per kind of motion platform.

    files        platform files and packaged platforms (`load_platform("kr500")`)
    serial       `SerialChain`: a serial robot, with or without a rail, read from its URDF
    urdf_chain   the joints of a URDF, read with Drake's parser or without it
    kinematics   the head frame's motion and the plant output y with derivatives (numpy)
    hexapod      a Stewart-platform hexapod's geometry, leg lengths of a pose and the
                 pose of leg lengths (numpy; its torch twin: `mca_drake.learning.legs`)

The torch twin of the kinematics lives in `mca_drake.learning.torch_plant`, the Drake
station in `mca_drake.systems`. Nothing below the app layer falls back to a default
platform: every function takes the platform it works on.
"""
