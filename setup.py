"""ament_python / pip package definition for initsel_ros."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'initsel_ros'

# ROS 2 comes from a real Jazzy install (apt, rosdep) or, on machines without one, from the
# PyPI wheels in the 'ros' extra. rclpy and the messages are never in install_requires, so
# pip never overwrites a real ROS install.
ros_wheels = ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces']

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(include=[package_name, f'{package_name}.*']),
    package_data={package_name: ['py.typed', 'synth/data/*.txt']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{package_name}']),
        (f'share/{package_name}', ['package.xml']),
        (f'share/{package_name}/config', sorted(glob('config/*.*'))),
        (f'share/{package_name}/launch', sorted(glob('launch/*.launch.py'))),
    ],
    python_requires='>=3.10',
    install_requires=[
        'numpy>=1.24',
        'opencv-python-headless>=4.8',
        'scikit-learn>=1.3',
        'scipy>=1.11',
        'tqdm>=4.60',
        'PyYAML>=6',
        'rosbags>=0.10',
        'setuptools',
    ],
    extras_require={
        'ros': ros_wheels,
        'test': ['pytest>=7', 'hypothesis>=6', 'ruff>=0.5', 'pycolmap==4.2.1'],
        'plot': ['matplotlib>=3.7'],
        'cluster': ['dask[distributed]>=2024.1'],
    },
    zip_safe=True,
    maintainer='initsel_ros developers',
    maintainer_email='initsel-ros@example.org',
    description='Decides when and with which method a monocular SLAM system initializes its map.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'selector = initsel_ros.ros.node:main',
            'initsel-selector = initsel_ros.ros.node:main',
            'initsel = initsel_ros.cli:main',
        ],
    },
)
