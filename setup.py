"""ament_python setup for leadscrew_sim."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'leadscrew_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'bench']),
    # the commissioning report's page template, read beside its module
    package_data={'leadscrew_sim.offline.commission': ['report_template.html']},
    data_files=[
        ('share/ament_index/resource_index/packages',
            ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + package_name + '/launch', sorted(glob('launch/*.launch.py'))),
        ('share/' + package_name + '/urdf', sorted(glob('urdf/*.xacro'))),
        ('share/' + package_name + '/doc/foxglove', sorted(glob('doc/foxglove/*.json'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='leadscrew_sim developers',
    maintainer_email='leadscrew-sim@example.com',
    description='Lead screw axis simulator with thread friction, '
                'self-locking, backlash and stick-slip.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'leadscrew_sim_node = leadscrew_sim.ros.node:main',
            'leadscrew_sim = leadscrew_sim.cli:main',
        ],
    },
)
