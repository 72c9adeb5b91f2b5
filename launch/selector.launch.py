"""Launch the initsel_ros ``selector`` node.

    ros2 launch initsel_ros selector.launch.py image:=/camera/image_raw \
        camera_info:=/camera/camera_info namespace:=cam1 params_file:=my_selector.yaml

Arguments:
    namespace: namespace of the node ('' = root); its ~/status etc. move with it.
    image: the image topic (remaps image_raw); with image_transport 'compressed' the node
        subscribes <image>/compressed.
    camera_info: the CameraInfo topic (remaps camera_info).
    params_file: parameter file (default: the package's share/initsel_ros/config/selector.yaml,
        whose `/**/selector:` section matches the node in any namespace).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

ARGUMENTS = (
    ('namespace', '', 'namespace of the selector node'),
    ('image', 'image_raw', 'image topic remapped to image_raw'),
    ('camera_info', 'camera_info', 'CameraInfo topic remapped to camera_info'),
    ('params_file',
     PathJoinSubstitution([FindPackageShare('initsel_ros'), 'config', 'selector.yaml']),
     'parameter file of the selector node'),
)


def generate_launch_description() -> LaunchDescription:
    """The launch arguments and the selector node."""
    declared = [DeclareLaunchArgument(name, default_value=default, description=description)
                for name, default, description in ARGUMENTS]
    selector = Node(
        package='initsel_ros',
        executable='selector',
        name='selector',
        namespace=LaunchConfiguration('namespace'),
        parameters=[LaunchConfiguration('params_file')],
        remappings=[
            ('image_raw', LaunchConfiguration('image')),
            ('camera_info', LaunchConfiguration('camera_info')),
        ],
        output='screen',
        emulate_tty=True,
    )
    return LaunchDescription([*declared, selector])
