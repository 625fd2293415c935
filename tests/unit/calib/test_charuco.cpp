// ChArUco boards in calib (calib/board.h): the board parsed from the command line's words and
// its errors, and the printed pattern handed to the simulator (charuco_pattern) against
// OpenCV's own drawing of the board, cell by cell, and its corners against OpenCV's.
#include <gtest/gtest.h>

#include <string>

#include <opencv2/aruco/charuco.hpp>

#include "calib/board.h"
#include "sdk/core/error.h"
#include "tests/support/test_support.h"

namespace sls::calib {
namespace {

TEST(Charuco, ParsesTheBoardAndNamesWhatIsWrong) {
  const BoardSpec chessboard = parse_board_spec("9x7", 0.0006, 0.0, "");
  EXPECT_FALSE(chessboard.is_charuco());
  EXPECT_EQ(chessboard.inner_cols, 9);
  const BoardSpec board = parse_board_spec("charuco:12x9", 0.0012, 0.0009, "");
  ASSERT_TRUE(board.is_charuco());
  EXPECT_EQ(board.inner_cols, 11);
  EXPECT_EQ(board.inner_rows, 8);
  EXPECT_EQ(board.dictionary, "DICT_5X5_100");
  EXPECT_EQ(parse_board_spec("charuco:5x5", 1.0, 0.5, "apriltag_36h11").dictionary, "DICT_APRILTAG_36H11");
  EXPECT_NE(test::message_of([] { parse_board_spec("charuco:12x9", 0.0012, 0.0009, "DICT_9X9_1"); })
                .find("unknown ArUco dictionary 'DICT_9X9_1' (known: "),
            std::string::npos);
  EXPECT_NE(test::message_of([] { parse_board_spec("charuco:12x9", 0.0012, 0.0012, ""); })
                .find("marker size 0.0012 m must be smaller than the square size 0.0012 m"),
            std::string::npos);
  EXPECT_NE(test::message_of([] { parse_board_spec("charuco:12x9", 0.0012, 0.0, ""); }).find("needs --marker"),
            std::string::npos);
  EXPECT_NE(test::message_of([] { parse_board_spec("9x7", 0.0012, 0.0009, ""); }).find("describe a ChArUco board"),
            std::string::npos);
  EXPECT_NE(test::message_of([] { parse_board_spec("charuco:20x20", 1.0, 0.5, "DICT_4X4_50"); })
                .find("needs 200 markers; the dictionary DICT_4X4_50 has 50"),
            std::string::npos);
}

// The table the simulator renders is OpenCV's board: each square's and cell's centre, looked
// up in the image CharucoBoard::draw makes (board x right, y down, one square 70 pixels).
TEST(Charuco, PatternIsOpenCVsDrawingAndItsCorners) {
  for (const std::string dictionary : {"DICT_5X5_100", "DICT_4X4_50", "DICT_6X6_250"}) {
    const BoardSpec board = parse_board_spec("charuco:7x5", 0.01, 0.007, dictionary);
    const BoardPattern pattern = charuco_pattern(board);
    EXPECT_EQ(pattern.cells, dictionary == "DICT_4X4_50" ? 6 : dictionary == "DICT_5X5_100" ? 7 : 8);
    const cv::Ptr<cv::aruco::CharucoBoard> cv_board = cv::aruco::CharucoBoard::create(
        7, 5, 1.0f, 0.7f, cv::aruco::getPredefinedDictionary(dictionary == "DICT_5X5_100"   ? cv::aruco::DICT_5X5_100
                                                             : dictionary == "DICT_4X4_50" ? cv::aruco::DICT_4X4_50
                                                                                           : cv::aruco::DICT_6X6_250));
    constexpr int kPixels = 700;  // per square: a cell of a 6x6 marker is 61 pixels
    cv::Mat image;
    cv_board->draw(cv::Size(7 * kPixels, 5 * kPixels), image, 0, 1);
    int dark_cells = 0;
    for (int j = 0; j < 5; ++j) {
      for (int i = 0; i < 7; ++i) {
        const std::size_t square = static_cast<std::size_t>(j * 7 + i);
        // Near the square's corner: outside any marker.
        const bool drawn_dark = image.at<std::uint8_t>(j * kPixels + 5, i * kPixels + 5) < 128;
        ASSERT_EQ(pattern.dark_square[square] != 0, drawn_dark) << dictionary << " square " << i << ", " << j;
        if (drawn_dark) continue;
        for (int r = 0; r < pattern.cells; ++r) {
          for (int c = 0; c < pattern.cells; ++c) {
            const double cell = 0.7 * kPixels / pattern.cells;
            const int x = static_cast<int>(i * kPixels + 0.15 * kPixels + (c + 0.5) * cell);
            const int y = static_cast<int>(j * kPixels + 0.15 * kPixels + (r + 0.5) * cell);
            const bool dark = image.at<std::uint8_t>(y, x) < 128;
            const std::size_t k = square * static_cast<std::size_t>(pattern.cells * pattern.cells) +
                                  static_cast<std::size_t>(r * pattern.cells + c);
            ASSERT_EQ(pattern.dark_cells[k] != 0, dark) << dictionary << " square " << i << ", " << j << " cell " << r
                                                        << ", " << c;
            dark_cells += dark ? 1 : 0;
          }
        }
      }
    }
    EXPECT_GT(dark_cells, 0);
    // Corner k of object_points() is OpenCV's chessboardCorners[k], one square from its origin.
    const std::vector<Eigen::Vector3d> points = board.object_points();
    ASSERT_EQ(points.size(), cv_board->chessboardCorners.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
      EXPECT_NEAR(points[k].x(), (static_cast<double>(cv_board->chessboardCorners[k].x) - 1.0) * 0.01, 1e-12) << k;
      EXPECT_NEAR(points[k].y(), (static_cast<double>(cv_board->chessboardCorners[k].y) - 1.0) * 0.01, 1e-12) << k;
    }
  }
}

}  // namespace
}  // namespace sls::calib
