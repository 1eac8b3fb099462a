# The Debian package (docs/packaging.md): `cpack -G DEB` in the build folder (or
# `cmake --build build --target package`) makes lipdrive_<version>_<arch>.deb of what
# `cmake --install` installs, under /usr, plus the documentation Debian asks for and the
# maintainer scripts (packaging/postinst, prerm, postrm). Depends are read off the linked
# shared libraries by dpkg-shlibdeps, plus what the daemon uses without linking it.

# Debian's documentation: the man page and the changelog gzipped as policy wants (-9n: no
# name or time stamp, so the same tree makes the same bytes).
set(LIPDRIVE_PACKAGING_DIR ${CMAKE_BINARY_DIR}/packaging)
foreach(doc lipdrive.1 changelog)
  add_custom_command(
    OUTPUT ${LIPDRIVE_PACKAGING_DIR}/${doc}.gz
    COMMAND ${CMAKE_COMMAND} -E make_directory ${LIPDRIVE_PACKAGING_DIR}
    COMMAND gzip -9n -c ${PROJECT_SOURCE_DIR}/packaging/${doc} > ${LIPDRIVE_PACKAGING_DIR}/${doc}.gz
    DEPENDS ${PROJECT_SOURCE_DIR}/packaging/${doc}
    VERBATIM)
endforeach()
add_custom_target(package_docs ALL DEPENDS ${LIPDRIVE_PACKAGING_DIR}/lipdrive.1.gz ${LIPDRIVE_PACKAGING_DIR}/changelog.gz)
install(FILES ${LIPDRIVE_PACKAGING_DIR}/lipdrive.1.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
install(FILES ${LIPDRIVE_PACKAGING_DIR}/changelog.gz packaging/copyright
        DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/lipdrive)

# cpack packages what is built: it does not first build every target (tests included), which a
# partial build would otherwise wait for inside test_package.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY TRUE)
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME lipdrive)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "lipdrive maintainers <maintainers@lipdrive.example>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "live mouth parameters from a head-mounted camera")
# The extended description: CPack puts the summary above it, indents each line and turns the
# empty line into Debian's paragraph break.
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "lipdrive tracks the performer's face in every camera frame, fits a 3D
morphable model of the character's head, measures the mouth and drives an
animatronic figure or a display over Modbus, serial lines, GPIO, DMX and OSC,
easing to a neutral pose when tracking is lost.

This package holds the daemon (lipdrive.service, enabled on install), its
configuration in /etc/lipdrive, the default models and a replay clip for the
simulated camera.")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # lipdrive_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION video)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
# Installed as the unit expects: /usr/bin/lipdrive, /etc/lipdrive/lipdrive.toml.
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# Everything `cmake --install` installs but the compact predictor, which postinst makes from
# libdlib-data's on the rig.
set(CPACK_INSTALL_CMAKE_PROJECTS "${CMAKE_BINARY_DIR};${PROJECT_NAME};Unspecified;/")
# Not linked, but used: dlib's landmark predictor (postinst converts it to the default [tracker]
# predictor), the maintainer scripts' systemd-sysusers and deb-systemd-helper. olad only for DMX
# output; opencv-data's face cascade only for photographs `lipdrive process` reads.
set(CPACK_DEBIAN_PACKAGE_DEPENDS
    "libdlib-data, systemd | systemd-standalone-sysusers | systemd-sysusers, init-system-helpers (>= 1.65~)")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "ola, opencv-data")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/packaging/postinst ${PROJECT_SOURCE_DIR}/packaging/prerm
    ${PROJECT_SOURCE_DIR}/packaging/postrm ${PROJECT_SOURCE_DIR}/packaging/conffiles)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)
include(CPack)
